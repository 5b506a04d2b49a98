"""Crease (and end) rules of degree d solved from S M = M T ([KSD] sec. 3.1-3.2.3).

The half-line setting of [KSD] sec. 3.1: ``B`` are the B-splines of degree d over the knots
``[0 x (d+1), 2, 4, 6, ...]`` (a crease or sharp end at t = 0; the other side of an interior
crease is the mirror image), ``b`` the same over the halved knots, ``B = b S`` (S by knot
insertion).  A subspace ``N = B M`` with subdivision matrix ``T`` (``N = n T``, ``n = b M``)
exists iff

    S M = M T                                                              [KSD] eq. (2)

Structure imposed (the relaxed conditions of [KSD] sec. 3.2.1, generalised to any d):

- ``J = d - floor((d - 1) / 2)`` crease functions N_0 .. N_(J-1) are combinations of
  B_0 .. B_(d-1); N_j for j >= J is the uniform B-spline B_(j + d - J).  Column j of M has
  support rows ``k <= j + floor((d - 1) / 2)`` (the band of (4), (8) and of M_4), row 0 of M is
  ``e_0`` (only B_0 is non-zero at t = 0) and the rows of M sum to one (partition of unity).
- T's row 0 is ``e_0`` (the crease point stays: ``c(0) = P_0``), rows ``1 .. r-1`` are
  unknown stencils on the columns ``j <= (i + J) / 2``, every row ``i >= r`` is the *uniform*
  stencil ``T_ij = binom(d + 1, i - 2 j + J) / 2^d`` even where it touches N_0 (the bold
  entries of (4), (5), (9)).
- The natural configuration at the crease is linear: every N_j has ``N_j^(2k)(0) = 0`` for
  k = 1 .. floor((d - 1) / 2).  For odd d this follows from the structure (the spectra quoted
  after (5) and (9): 1, 1/2, 1/8, 1/32, ...); for d = 4 the structure alone has three
  solutions (``crease_scheme_solutions``: a second one with spectrum 1, 1/2, 1/4, 1/16,
  quadratic instead of cubic precision at the crease, and a degenerate one with
  N_0 = B_0 + B_1 and a negative weight), and the condition picks the paper's M_4, T_4 (the
  printed display of sec. 3.2.3, reproduced to round-off); for d = 6 the structure has one
  solution, which satisfies the condition (the paper prints no T_6).  The solution counts
  were cross-checked by an exact polynomial solve of the same system (sympy, not a
  dependency: 3 real solutions for d = 4, 1 for d = 6).

For given T entries the equations are linear in M; the few T entries (2 for d = 5, 5 for
d = 7) are found by a least-squares solve of the remaining residual (variable projection),
started from the uniform stencils, and the solution is accepted only if SM - MT vanishes to
round-off.  ``r = J - 1`` irregular rows suffice for odd d (r = 1, 2, 3 for d = 3, 5, 7, as in
(3), (5), (9)); even d needs ``r = J`` (the solve with J - 1 leaves a residual of 0.06 for
d = 4, 0.016 for d = 6), the row count of the paper's T_4.

Reading of the damaged text: in (4), the bold ``1 - m1 - m2`` entries are the row sums, and
T_5's row ``t_1 t_2 32 - t_1 - t_2`` is a stencil summing to 32; the printed solutions (5),
(8), (9) and M_4, T_4 are reproduced by this solve to round-off (tests/test_curves_creases.py).
For odd d the result equals the ghost-point rule of [KSD] sec. 3.2.1 (uniform subdivision of
the polygon extended by P_(-i) = 2 P_0 - P_i), ``ghost_reflection`` below.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import comb

import numpy as np
import scipy.sparse as sp

from .knots import insert_knots_matrix

__all__ = [
    "CreaseScheme", "crease_scheme", "crease_scheme_solutions", "half_line_subdivision", "ghost_reflection", "modified_quintic_step",
    "modified_quintic_operator",
]

#: SM - MT must vanish to this (double round-off of sums of ~10 terms of size <= 1)
SOLVE_TOLERANCE = 1e-12


@dataclass(frozen=True)
class CreaseScheme:
    """The crease rule of degree d on the half line t >= 0 ([KSD] sec. 3).

    ``M``: (d, J) the crease functions N_0..N_(J-1) in B_0..B_(d-1); ``T``: (r, c) the first
    r (irregular) rows of the subdivision matrix (stencils on P_0, P_1, ...); every later row i
    is the uniform stencil ``binom(d + 1, i - 2 j + J) / 2^d``.  ``M_full``, ``T_full``: the
    solved finite sections (for checks: S M = M T with ``S = half_line_subdivision``).
    """

    degree: int
    J: int
    r: int
    M: np.ndarray
    T: np.ndarray
    M_full: np.ndarray
    T_full: np.ndarray
    residual: float


def _regular(d: int, J: int, i: int, j: int) -> float:
    x = i - 2 * j + J
    return comb(d + 1, x) / 2.0**d if 0 <= x <= d + 1 else 0.0


def half_line_subdivision(degree: int, size: int) -> np.ndarray:
    """The leading (size x size) block of S, ``B = b S`` over ``[0 x (d+1), 2, 4, ...]``.

    Computed by inserting the knots 1, 3, 5, ... (Boehm); the block is closed (fine b_l,
    l < size, only take coarse B_k with k <= (l + d) / 2 < size).
    """
    d = degree
    L = size + d + 2
    t = np.r_[np.zeros(d + 1), 2.0 * np.arange(1, L + d + 2)]
    _, S = insert_knots_matrix(t, d, 2.0 * np.arange(L) + 1.0)
    return S[:size, :size]


def _structured_solver(d: int):
    """The bilinear system S M = M T of the module docstring's structure, as a solver.

    Returns ``solve(r, theta0, natural) -> (M, T, err)``: the T entries of rows 1 .. r-1
    (``theta``, started from ``theta0``, None = the uniform stencils) by least squares of the
    remaining residual, M linear in them; ``natural`` adds the linear natural configuration
    (``D^(2q) N_j(0) = 0``); ``err`` is the largest entry of S M - M T (and of the row sums).
    """
    from scipy.interpolate import BSpline  # here, not at import: scipy.interpolate and
    from scipy.optimize import least_squares  # scipy.optimize cost every CLI start ~0.5 s

    c = (d - 1) // 2
    J = d - c
    K = 3 * d + 6  # coarse B's in the finite section
    S = half_line_subdivision(d, K)
    nN = K - (d - J)
    free = [(k, j) for j in range(J) for k in range(1, d) if k <= j + c]
    tk = np.r_[np.zeros(d + 1), 2.0 * np.arange(1, K + 1)]
    eye = np.eye(len(tk) - d - 1)
    # even derivatives at 0 of B_0..B_(K-1): rows (order 2, 4, ..., 2c)
    D = np.array([[BSpline(tk, eye[k], d).derivative(2 * q)(0.0) for k in range(K)] for q in range(1, c + 1)])
    M0 = np.zeros((K, nN))
    for j in range(J, nN):
        M0[j + d - J, j] = 1.0
    M0[0, 0] = 1.0
    rows_used, cols_used = K - 2 * d, nN - d  # equations away from the truncation
    E = np.zeros((len(free), K, nN))
    for e, (k, j) in enumerate(free):
        E[e, k, j] = 1.0
    # partition of unity on the crease block's rows
    Cs = np.zeros((d, len(free)))
    for e, (k, j) in enumerate(free):
        Cs[k, e] = 1.0
    rs = (1.0 - M0.sum(axis=1))[:d]
    # linear natural configuration: D^(2q) N_j (0) = 0
    Dr, Db = [], []
    for q in range(c):
        for j in range(J):
            row = np.zeros(len(free))
            for e, (k, jj) in enumerate(free):
                if jj == j:
                    row[e] = D[q, k]
            Dr.append(row)
            Db.append(-D[q] @ M0[:, j])

    def solve(r: int, theta0: np.ndarray | None = None, natural: bool = True):
        tfree = [(i, j) for i in range(1, r) for j in range((i + J) // 2 + 1)]

        def build_T(theta):
            T = np.array([[_regular(d, J, i, j) for j in range(nN)] for i in range(nN)])
            T[:r] = 0.0
            T[0, 0] = 1.0
            for (i, j), v in zip(tfree, theta):
                T[i, j] = v
            return T

        def fit_M(theta):
            T = build_T(theta)
            A = np.array([(S @ Ee - Ee @ T)[:rows_used, :cols_used].ravel() for Ee in E]).T
            b = -(S @ M0 - M0 @ T)[:rows_used, :cols_used].ravel()
            extra = [np.array(Dr)] if (Dr and natural) else []
            A2 = np.vstack([A, Cs] + extra)
            b2 = np.r_[b, rs, Db] if extra else np.r_[b, rs]
            mu = np.linalg.lstsq(A2, b2, rcond=None)[0]
            M = M0.copy()
            for (k, j), v in zip(free, mu):
                M[k, j] = v
            return M, T, A2 @ mu - b2

        def residual(theta):
            sums = [sum(v for (i, _), v in zip(tfree, theta) if i == ii) - 1.0 for ii in range(1, r)]
            return np.r_[fit_M(theta)[2], sums]

        if theta0 is None:
            theta0 = np.array([_regular(d, J, i, j) for (i, j) in tfree])
        if len(theta0):
            theta = least_squares(residual, theta0, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        else:
            theta = theta0
        M, T, res = fit_M(theta)
        err = float(np.abs(S @ M - M @ T)[:rows_used, :cols_used].max())
        err = max(err, float(np.abs(residual(theta)).max()) if len(theta) else err)
        if err < SOLVE_TOLERANCE:
            # The solution is rational: snap to the nearest fractions of small denominator
            # and keep them if they solve S M = M T better (round-off 1e-14 -> 1e-16).
            Ms, Ts = _snap(M), _snap(T)
            err_s = float(np.abs(S @ Ms - Ms @ Ts)[:rows_used, :cols_used].max())
            if err_s <= err:
                M, T, err = Ms, Ts, err_s
        return M, T, err

    solve.n_theta = lambda r: sum((i + J) // 2 + 1 for i in range(1, r))
    return solve, J


@lru_cache(maxsize=None)
def crease_scheme(degree: int) -> CreaseScheme:
    """Solve S M = M T for the crease rule of degree ``degree`` (module docstring)."""
    d = degree
    solve, J = _structured_solver(d)
    for r in (J - 1, J):
        if r < 1:
            continue
        M, T, err = solve(r)
        if err < SOLVE_TOLERANCE:
            return CreaseScheme(d, J, r, M[:d, :J].copy(), T[:r, : J + 2].copy(), M, T, err)
    raise RuntimeError(f"no crease scheme of degree {d} solves S M = M T (residual {err:.2e})")


@lru_cache(maxsize=None)
def crease_scheme_solutions(degree: int, starts: int = 40) -> tuple[CreaseScheme, ...]:
    """Every crease rule of the module docstring's structure *without* the natural
    configuration condition that ``crease_scheme`` adds: the distinct solutions of S M = M T
    found from the uniform stencils and ``starts`` random starts (fixed seed), r = J rows.

    For d = 4 these are three ([KSD]'s T_4, rows (10, 5, 1)/16 and (2, 9, 5)/16, spectrum
    1, 1/2, 1/8, 1/16; a second one, rows (60, 50, 2)/112 and (12, 66, 34)/112, spectrum 1, 1/2,
    1/4, 1/16; and a degenerate one with N_0 = B_0 + B_1 and a negative weight, rows
    (15, 5/4, -1/4)/16, (3, 33/4, 19/4)/16); for d = 6 one (the ``crease_scheme``).  The
    counts were cross-checked by an exact polynomial solve of the same system (sympy, outside
    the package: 3 real solutions for d = 4, 1 for d = 6).  Used to show that the
    non-monotone vertex motion of even degrees (``runs.vertex_limit_weights``) is not the
    choice of one solution among several (docs/curves.md).
    """
    d = degree
    solve, J = _structured_solver(d)
    rng = np.random.default_rng(20141)
    found: list[CreaseScheme] = []
    nt = solve.n_theta(J)
    base = None
    for a in range(starts + 1):
        theta0 = base if a == 0 else rng.uniform(-0.5, 1.5, nt)
        M, T, err = solve(J, theta0, natural=False)
        if err >= SOLVE_TOLERANCE:
            continue
        Tr = T[:J, : J + 2]
        if any(np.abs(f.T - Tr).max() < 1e-9 for f in found):
            continue
        found.append(CreaseScheme(d, J, J, M[:d, :J].copy(), Tr.copy(), M, T, err))
    return tuple(found)


def _snap(A: np.ndarray) -> np.ndarray:
    """Each entry replaced by the nearest fraction with denominator <= 10^5 if within 1e-11."""
    out = A.copy()
    for idx, x in np.ndenumerate(A):
        f = Fraction(float(x)).limit_denominator(100000)
        if abs(float(f) - x) < 1e-11:
            out[idx] = float(f)
    return out


def ghost_reflection(index: int, n: int, left: bool, right: bool) -> dict[int, float]:
    """Point ``index`` of a run ``P_0..P_(n-1)`` extended by odd reflection at crease ends.

    ``P_(-i) = 2 P_0 - P_i`` at a left crease, ``P_(n-1+i) = 2 P_(n-1) - P_(n-1-i)`` at a right
    one ([KSD] sec. 3.2.1 and 3.2.3, ghost points), applied until the index is inside; returns
    the weights {run index: weight}.  An index beyond a free end raises ValueError.
    """
    if 0 <= index < n:
        return {index: 1.0}
    if index < 0:
        if not left:
            raise ValueError("index beyond a free end")
        out = {0: 2.0}
        for k, w in ghost_reflection(-index, n, left, right).items():
            out[k] = out.get(k, 0.0) - w
        return out
    if not right:
        raise ValueError("index beyond a free end")
    out = {n - 1: 2.0}
    for k, w in ghost_reflection(2 * (n - 1) - index, n, left, right).items():
        out[k] = out.get(k, 0.0) - w
    return out


def modified_quintic_step(n: int, closed: bool, sharpness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``modified_quintic_operator`` as a dense matrix (small polygons, figures)."""
    A, child = modified_quintic_operator(n, closed, sharpness)
    return A.toarray(), child


def modified_quintic_operator(n: int, closed: bool, sharpness: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """One step of the modified quintic scheme T~5 ([KSD] sec. 3.2.2, eq. (7)): (n' x n) sparse.

    At a sharp vertex the vertex point is P_v ([SSEL13]/32) and the two adjacent edge points are
    midpoints ([16, 16]/32); every other point takes the uniform quintic stencils
    [6, 20, 6]/32 and [1, 15, 15, 1]/32 on its own side of the crease (P_v counted as an
    ordinary point there).  0 < s < 1 blends these rows with the smooth ones by s; children of
    sharp vertices get s - 1.  The child of P_i is point 2 i.  T~5 does not solve S M = M T:
    its limit has infinitely many polynomial pieces near a crease, so it is exported by
    refinement to a tolerance (``curve.modified_quintic_limit``), never exactly.
    Open polygons: end vertices are sharp, the curve starts there.
    """
    s = np.asarray(sharpness, dtype=np.float64).copy()
    if not closed:
        s[[0, n - 1]] = np.inf
    m = 2 * n if closed else 2 * n - 1
    i = np.arange(n)
    interior = np.ones(n, dtype=bool) if closed else (i > 0) & (i < n - 1)
    w = np.where(s >= 1, 1.0, s)
    w = np.where(interior, w, 1.0)
    rows = [2 * i]
    cols = [i]
    vals = [w]
    for off, c in ((-1, 6), (0, 20), (1, 6)):  # smooth vertex rule, blended by 1 - w
        rows.append(2 * i[interior])
        cols.append((i[interior] + off) % n)
        vals.append((1 - w[interior]) * c / 32)
    e = np.arange(n if closed else n - 1)
    j = (e + 1) % n
    ok = np.ones(len(e), dtype=bool) if closed else (e >= 1) & (j <= n - 2)
    we = np.where(ok, np.minimum(1.0, np.maximum(np.minimum(s[e], 1.0), np.minimum(s[j], 1.0))), 1.0)
    rows += [2 * e + 1, 2 * e + 1]
    cols += [e, j]
    vals += [0.5 * we, 0.5 * we]
    for off, c in ((-1, 1), (0, 15), (1, 15), (2, 1)):  # smooth edge rule, blended by 1 - w
        rows.append(2 * e[ok] + 1)
        cols.append((e[ok] + off) % n)
        vals.append((1 - we[ok]) * c / 32)
    A = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, n)).tocsr()
    A.eliminate_zeros()
    child = np.zeros(m)
    child[0::2] = np.where(s >= 1, s - 1, 0.0)
    return A, child
