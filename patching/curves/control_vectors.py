"""Control vectors on uniform subdivision curves of degree d ([KSD] sec. 4).

The curve is ``c(t) = sum_i N_i(t) P_i + sum_j N^_d(t - t_j) V_j`` ([KSD] eq. (11)): uniform
B-splines N_i plus, at each control vector V_j, the crease function N^_d, a spline with a
d-fold knot at t_j (C0 there) of minimal support ``2 floor(d/2)`` spans.  Refinability of
``N = (..., N_i, ..., N^_d, ...)`` is again S M = M T ([KSD] eq. (2)), S now the
subdivision matrix of the B-splines over ``(..., -4, -2, 0 x d, 2, 4, ...)``.  With the
contribution of N^_d to its refined copy fixed to 1/2 (the caption of [KSD] Table 1), the
unknowns enter linearly:

    S m = 1/2 shift(m) + U c,   m_0 = 1                                                (1)

m: the coefficients of N^_d on the B-splines with knots in ``[-2w, 2w]`` (w = floor(d/2));
c: its mask on the fine uniform B-splines inside that support (the extra column of T);
``m_0 = N^_d(0) = 1`` (the central element of [KSD] eq. (14)).  The solution is unique (the
system has nullity 1 before normalising, checked in ``crease_function``) and reproduces
[KSD] Table 1 for d = 2..7 (tests/test_curves_control_vectors.py); the paper's Groebner-basis
route (t_4 unknown, floor(d/2) roots) is not needed once t_4 = 1/2.

Where the crease sits: odd d at the parameter of the vertex's B-spline centre (vertex v);
even d at the knot between P_v and P_(v+1) (even-degree B-splines are centred on spans, not
knots, so a vertex has no knot of its own; [KSD] sec. 4 notes that even-degree creases "are
not so natural").  Sharpness s of a vector: for s >= 1 it takes part in the step and its
child (V/2 at the same place) gets s - 1 (kept while that is > 0); for 0 < s < 1 its contribution is scaled by s and
it is dropped; s = inf keeps it for ever (a C0 crease in the limit).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .knots import clamp_matrix, insert_knots_matrix
from .uniform import uniform_knots, uniform_subdivision

__all__ = ["CreaseFunction", "crease_function", "vector_step", "vector_limit", "vectors_on_limit", "crease_parameter"]


@dataclass(frozen=True)
class CreaseFunction:
    """N^_d: ``coefficients`` on the 2w - 1 B-splines around its d-fold knot (unit spans),
    ``mask`` on the 4w - d fine uniform B-splines (Table 1, without the 1/2 on itself)."""

    degree: int
    coefficients: np.ndarray
    mask: np.ndarray
    residual: float


@lru_cache(maxsize=None)
def crease_function(degree: int) -> CreaseFunction:
    """Solve (1) for the crease function of degree ``degree`` ([KSD] sec. 4, Table 1)."""
    d = degree
    w = d // 2
    L = 2 * w + d + 3
    tc = np.r_[2.0 * np.arange(-L, 0), np.zeros(d), 2.0 * np.arange(1, L + 1)]
    nc = len(tc) - d - 1
    odd = np.r_[2.0 * np.arange(-L, 0) + 1, 2.0 * np.arange(0, L) + 1]
    odd = odd[(odd > tc[d]) & (odd < tc[nc])]
    tf, S = insert_knots_matrix(tc, d, odd)
    nf = len(tf) - d - 1
    inside = [k for k in range(nc) if tc[k] >= -2 * w and tc[k + d + 1] <= 2 * w]
    tu = np.r_[tf[tf < 0], 0.0, tf[tf > 0]]  # the fine uniform knots (0 once)
    tu2, Uall = insert_knots_matrix(tu, d, [0.0] * (d - 1))
    assert np.allclose(tu2, tf)
    ucols = [i for i in range(len(tu) - d - 1) if tu[i] >= -2 * w and tu[i + d + 1] <= 2 * w]
    off = list(tf).index(-1.0) - list(tc).index(-2.0)
    A = np.zeros((nf, len(inside) + len(ucols)))
    for e, k in enumerate(inside):
        A[:, e] = S[:, k]
        A[k + off, e] -= 0.5
    A[:, len(inside) :] = -Uall[:, ucols]
    if A.shape[1] - np.linalg.matrix_rank(A) != 1:
        raise RuntimeError(f"the crease function of degree {d} is not unique")
    central = inside.index(list(tc).index(-2.0))
    norm = np.zeros(A.shape[1])
    norm[central] = 1.0
    A2 = np.vstack([A, norm])
    b = np.zeros(nf + 1)
    b[-1] = 1.0
    x = np.linalg.lstsq(A2, b, rcond=None)[0]
    res = float(np.abs(A2 @ x - b).max())
    return CreaseFunction(d, x[: len(inside)], x[len(inside) :], res)


def crease_parameter(v: int, n: int, degree: int, closed: bool) -> float:
    """Parameter of vertex v's crease on the knots of ``uniform.uniform_knots``: the centre of
    P_v's B-spline (odd d) or the knot half a span after it (even d)."""
    d = degree
    knots, W = uniform_knots(n, d, closed)
    pole = int(W.tocsc()[:, v].indices[0]) if closed else v
    centre = (knots[pole] + knots[pole + d + 1]) / 2.0
    return centre if d % 2 else centre + 0.5


def _refined_parameter(u: float, n: int, d: int, closed: bool) -> float:
    """Where parameter u of the polygon lies after one uniform step (t -> 2 t + delta)."""
    a = uniform_knots(n, d, closed)[0][d]
    n2 = uniform_subdivision(n, d, closed).shape[0]
    a2 = uniform_knots(n2, d, closed)[0][d]
    return 2.0 * u + (a2 - 2.0 * a)


def vector_step(
    n: int, degree: int, closed: bool, params: np.ndarray, sharpness: np.ndarray
) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, np.ndarray, np.ndarray]:
    """One step with control vectors at crease parameters ``params``:
    ``(A, C, H, new_params, new_sharpness)``.

    New points = A @ P + C @ V: A the uniform step, C the mask of N^_d ([KSD] Table 1) on the
    fine points whose B-splines lie inside N^_d's support, scaled by min(s, 1); new vectors =
    H @ V, 1/2 of each vector with s > 1 at the refined parameter (Table 1's caption).
    """
    d = degree
    A = uniform_subdivision(n, d, closed)
    n2 = A.shape[0]
    mask = crease_function(d).mask
    w = d // 2
    fk, FW = uniform_knots(n2, d, closed)
    pole_to_point = FW.tocoo()
    point_of = np.empty(FW.shape[0], dtype=int)
    point_of[pole_to_point.row] = pole_to_point.col
    rows, cols, vals, keep = [], [], [], []
    for e, (u, s) in enumerate(zip(params, sharpness)):
        if s <= 0:
            continue
        uf = _refined_parameter(float(u), n, d, closed)
        lo, hi = uf - 2 * w, uf + 2 * w
        poles = [f for f in range(FW.shape[0]) if fk[f] >= lo - 1e-9 and fk[f + d + 1] <= hi + 1e-9]
        if closed:
            poles = poles[: len(mask)]  # the periodic copies repeat the first d poles
        if len(poles) != len(mask):
            # near a free end some of the fine B-splines do not meet the domain: keep the rest
            first = int(round(lo - fk[0]))
            poles_all = list(range(first, first + len(mask)))
            sel = [(k, f) for k, f in enumerate(poles_all) if 0 <= f < FW.shape[0]]
        else:
            sel = list(enumerate(poles))
        for k, f in sel:
            rows.append(point_of[f])
            cols.append(e)
            vals.append(mask[k] * min(float(s), 1.0))
        if s > 1:  # its child has sharpness s - 1 > 0 (s = 1: full this step, then dropped)
            keep.append(e)
    C = sp.coo_matrix((vals, (rows, cols)), shape=(n2, len(params))).tocsr()
    H = sp.coo_matrix((np.full(len(keep), 0.5), (np.arange(len(keep)), keep)), shape=(len(keep), len(params))).tocsr()
    new_u = np.array([_refined_parameter(float(params[e]), n, d, closed) for e in keep])
    new_s = np.array([sharpness[e] - 1.0 if np.isfinite(sharpness[e]) else np.inf for e in keep])
    return A, C, H, new_u, new_s


def vector_limit(
    n: int, degree: int, closed: bool, params: np.ndarray
) -> tuple[np.ndarray, sp.csr_matrix, sp.csr_matrix]:
    """Exact limit with infinitely sharp vectors at crease parameters ``params``:
    ``(knots, W, E)``, poles = W @ P + E @ V on clamped knots starting at 0.

    The uniform B-spline gets d - 1 extra copies of each crease knot (multiplicity d) and the
    coefficients of N^_d are added on the B-splines around it.
    """
    d = degree
    knots, W0 = uniform_knots(n, d, closed)
    a = knots[d]
    if closed:  # a crease at the seam parameter is also at the other end: move it inside
        period = float(n)
        params = [a + ((u - a) % period) for u in params]
    knots2, A = insert_knots_matrix(knots, d, [u for u in sorted(params) for _ in range(d - 1)])
    W = A @ W0.toarray()
    E = _crease_columns(knots2, d, params, W.shape[0])
    kc, Cl = clamp_matrix(knots2, d)
    return kc - kc[0], sp.csr_matrix(Cl @ W), sp.csr_matrix(Cl @ E)


def _crease_columns(knots2: np.ndarray, d: int, params, n_poles: int) -> np.ndarray:
    """N^_d's coefficients at each crease parameter u (already a d-fold knot of ``knots2``)."""
    coef = crease_function(d).coefficients
    E = np.zeros((n_poles, len(params)))
    for e, u in enumerate(params):
        first = int(np.searchsorted(knots2, u - 1e-9, side="left"))
        central = first - 1  # the B-spline with knots (u - 1, u x d, u + 1)
        idx = central + np.arange(len(coef)) - (len(coef) - 1) // 2
        E[idx, e] += coef
    return E


def vectors_on_limit(
    knots: np.ndarray, W: sp.csr_matrix, degree: int, vertices
) -> tuple[np.ndarray, sp.csr_matrix, sp.csr_matrix]:
    """Infinitely sharp vectors at ``vertices`` added to a limit ``(knots, W)`` of points (a
    corner limit, ``runs.limit_operator``): ``(knots', W', E)``, poles = W' @ P + E @ V.

    The vector at v sits where v's uniform B-spline is a B-spline of the limit (the pole whose
    row of W is P_v alone): at its centre (odd d) or half a span after it (even d), as
    ``crease_parameter`` puts it on the uniform curve.  Its crease knot gets d - 1 more copies and
    N^_d's coefficients go on the B-splines around it, which must be uniform unit spans
    (``curve.VECTOR_CLEARANCE`` keeps tags that far away; a breach is a bug, RuntimeError).
    """
    d = degree
    w = d // 2
    Wr = sp.csr_matrix(W)
    Wc = Wr.tocsc()
    params = []
    for v in vertices:
        col = Wc.indices[Wc.indptr[v] : Wc.indptr[v + 1]]
        pure = [int(p) for p in col if Wr.indptr[p + 1] - Wr.indptr[p] == 1 and Wr[p, v] == 1.0]
        if len(pure) != 1:
            raise RuntimeError(f"vertex {v} has no uniform B-spline in the limit")
        p = pure[0]
        if not np.allclose(np.diff(knots[p : p + d + 2]), 1.0):
            raise RuntimeError(f"vertex {v}'s B-spline is not uniform in the limit")
        u = 0.5 * (knots[p] + knots[p + d + 1]) + (0.0 if d % 2 else 0.5)
        window = knots[(knots > u - w - 1 - 1e-9) & (knots < u + w + 1 + 1e-9)]
        if len(window) != 2 * w + 3 or not np.allclose(np.diff(window), 1.0):
            raise RuntimeError(f"the crease function at vertex {v} meets a non-uniform span")
        params.append(float(u))
    knots2, A = insert_knots_matrix(knots, d, [u for u in sorted(params) for _ in range(d - 1)], sparse=True)
    E = _crease_columns(knots2, d, params, A.shape[0])
    return knots2, (A @ Wr).tocsr(), sp.csr_matrix(E)
