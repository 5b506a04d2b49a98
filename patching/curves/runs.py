"""Runs between sharp vertices: their spline spaces, refinement operators and limits.

A polygon is cut at its sharp vertices into *runs* ``P_a .. P_b``; each end of a run is a
``"crease"`` (a sharp vertex: [KSD] sec. 3 rule, the curve passes through it) or ``"free"``
(an untagged end of an open polygon: uniform rule, the curve covers the full spans only).

The limit of a run is a spline ``c = sum_k B_k (M P)_k`` over clamped knots on ``[0, m]``
(unit spans; ``m = n - d + (d - J) * #creases``, J from ``creases.crease_scheme``), built in
one of two ways:

- ``"ghost"`` (odd d, any run length): the uniform B-spline of the run extended by odd
  reflection at its crease ends, P_(-i) = 2 P_0 - P_i ([KSD] sec. 3.2.1, 3.2.3), clamped;
- ``"blocks"`` (any d): the crease functions N_0..N_(J-1) = B M of the solved scheme at each
  crease end (mirrored at the right end), uniform B-splines between; needs the two end blocks
  to be disjoint (n >= 2 J between two creases).

One subdivision step of a run is the matrix ``T_run`` with ``M_fine T_run = S M`` (S inserts
every span's midpoint), solved densely for short runs and assembled from the crease stencils
(first r rows of ``crease_scheme(d).T``, mirrored at a right crease) and the uniform stencil
``binom(d+1, i - 2 j + o) / 2^d`` for long ones; the tests check that both agree.
"""

from __future__ import annotations

import math
from functools import lru_cache
from itertools import combinations
from math import comb

import numpy as np
import scipy.sparse as sp

from ..errors import UnsupportedError
from .creases import crease_scheme, ghost_reflection
from .knots import clamp_matrix, insert_knots_matrix
from .uniform import uniform_knots, uniform_subdivision

__all__ = [
    "CREASE",
    "FREE",
    "run_spans",
    "run_refined_size",
    "run_space",
    "run_refinement",
    "runs_of",
    "step_operator",
    "semi_sharp_step",
    "limit_operator",
    "vertex_limit_weights",
    "fractional_even_limit",
]

CREASE = "crease"
FREE = "free"
#: residual above which a solved run operator is refused (round-off of ~10-term sums)
RUN_TOLERANCE = 1e-11


def _J(d: int) -> int:
    return d - (d - 1) // 2


def run_spans(n: int, d: int, left: str, right: str) -> int:
    """Spans m of the limit of a run of n points."""
    return n - d + (d - _J(d)) * ((left == CREASE) + (right == CREASE))


def run_refined_size(n: int, d: int, left: str, right: str) -> int:
    """Points of the run after one step: ``2 m + d - (d - J) * #creases``."""
    ncr = (left == CREASE) + (right == CREASE)
    return 2 * run_spans(n, d, left, right) + d - (d - _J(d)) * ncr


def _ghost_space(n: int, d: int, left: str, right: str) -> tuple[np.ndarray, np.ndarray]:
    c = (d - 1) // 2
    lo = -c if left == CREASE else 0
    hi = n - 1 + c if right == CREASE else n - 1
    G = np.zeros((hi - lo + 1, n))
    G[-lo + np.arange(n), np.arange(n)] = 1.0
    for i in [*range(lo, 0), *range(n, hi + 1)]:  # only the ghost points need reflecting
        for k, w in ghost_reflection(i, n, left == CREASE, right == CREASE).items():
            G[i - lo, k] += w
    h = (d + 1) // 2
    knots = np.arange(lo - h, hi + h + 1, dtype=np.float64) - (lo + c)
    return knots, G


def _block_space(n: int, d: int, left: str, right: str) -> tuple[np.ndarray, np.ndarray]:
    scheme = crease_scheme(d)
    J = scheme.J
    m = run_spans(n, d, left, right)
    lk = np.zeros(d + 1) if left == CREASE else np.arange(-d, 1, dtype=np.float64)
    rk = np.full(d + 1, float(m)) if right == CREASE else np.arange(m, m + d + 1, dtype=np.float64)
    knots = np.r_[lk, np.arange(1, m, dtype=np.float64), rk]
    nb = m + d
    M = np.zeros((nb, n))
    j0 = J if left == CREASE else 0
    j1 = n - J if right == CREASE else n
    shift = (d - J) if left == CREASE else 0
    for j in range(j0, j1):
        M[j + shift, j] = 1.0
    if left == CREASE:
        M[:d, :J] += scheme.M
    if right == CREASE:
        M[nb - d :, n - J :] += scheme.M[::-1, ::-1]
    return knots, M


def run_space(n: int, d: int, left: str, right: str, method: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The limit of a run: ``(knots, M)``, clamped on ``[0, m]``, poles = M @ P_run (dense)."""
    if method is None:
        method = "ghost" if d % 2 else "blocks"
    _check_run(n, d, left, right, method)
    knots, M = (_ghost_space if method == "ghost" else _block_space)(n, d, left, right)
    knots_c, A = clamp_matrix(knots, d)
    return knots_c, A @ M


def _check_run(n: int, d: int, left: str, right: str, method: str) -> None:
    J = _J(d)
    ncr = (left == CREASE) + (right == CREASE)
    if run_spans(n, d, left, right) < 1:
        raise UnsupportedError(f"a run of {n} points has no full span at degree {d}")
    if method == "ghost":
        if d % 2 == 0:
            raise ValueError("ghost points need an odd degree")
        if ncr == 1 and n < J:
            raise UnsupportedError(f"a run of {n} points from a sharp vertex to a free end is too short at degree {d}")
    else:
        need = {2: 2 * J, 1: J + 1, 0: d + 1}[ncr]
        if n < need:
            raise UnsupportedError(
                f"degree {d} needs at least {need} points from sharp vertex to sharp vertex or end, not {n}"
            )


@lru_cache(maxsize=4096)
def _solved_refinement(n: int, d: int, left: str, right: str, method: str) -> np.ndarray:
    knots, M = run_space(n, d, left, right, method)
    m = run_spans(n, d, left, right)
    fine_knots, S = insert_knots_matrix(2.0 * knots, d, 2.0 * np.arange(m) + 1.0)
    n2 = run_refined_size(n, d, left, right)
    knots2, M2 = run_space(n2, d, left, right, method)
    assert np.allclose(fine_knots, knots2)
    T = np.linalg.lstsq(M2, S @ M, rcond=None)[0]
    err = float(np.abs(M2 @ T - S @ M).max())
    if err > RUN_TOLERANCE:
        raise UnsupportedError(f"no degree-{d} subdivision rule for a run of {n} points ({left}-{right})")
    T[np.abs(T) < 1e-15] = 0.0
    return T


def _assembled_refinement(n: int, d: int, left: str, right: str) -> sp.csr_matrix:
    scheme = crease_scheme(d)
    J, r = scheme.J, scheme.r
    n2 = run_refined_size(n, d, left, right)
    o = J if left == CREASE else d
    rows, cols, vals = [], [], []
    lo = r if left == CREASE else 0
    hi = n2 - r if right == CREASE else n2
    for k in range(d + 2):
        w = comb(d + 1, k) / 2.0**d
        i = np.arange(lo, hi)
        i = i[(i + o - k) % 2 == 0]
        j = (i + o - k) // 2
        ok = (j >= 0) & (j < n)
        rows.append(i[ok])
        cols.append(j[ok])
        vals.append(np.full(int(ok.sum()), w))
    Tc = scheme.T
    ii, jj = np.nonzero(Tc)
    if left == CREASE:
        rows.append(ii)
        cols.append(jj)
        vals.append(Tc[ii, jj])
    if right == CREASE:
        rows.append(n2 - 1 - ii)
        cols.append(n - 1 - jj)
        vals.append(Tc[ii, jj])
    return sp.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n2, n)
    ).tocsr()


@lru_cache(maxsize=4096)
def _ghost_refinement(n: int, d: int, left: str, right: str) -> sp.csr_matrix:
    """Odd d: uniform stencils (1) on the run extended by odd reflection (exact, any length)."""
    _check_run(n, d, left, right, "ghost")
    n2 = run_refined_size(n, d, left, right)
    o = _J(d) if left == CREASE else d
    A = np.zeros((n2, n))
    for i in range(n2):
        for k in range(d + 2):
            if (i + o - k) % 2:
                continue
            j = (i + o - k) // 2
            for jj, w in ghost_reflection(j, n, left == CREASE, right == CREASE).items():
                A[i, jj] += w * comb(d + 1, k) / 2.0**d
    return sp.csr_matrix(A)


def run_refinement(n: int, d: int, left: str, right: str, method: str | None = None) -> sp.csr_matrix:
    """One subdivision step of a run: (n' x n) sparse, rows = new points.

    ``method``: ``"ghost"`` (odd d) uniform stencils on the reflected run (default for short
    odd runs); ``"assembled"`` the solved crease stencils + uniform rows (default for
    n >= 2 d + 2); ``"solved"`` the dense solve ``M_fine T = S M`` of the run's spline spaces
    (default for short even runs).
    """
    if method is None:
        # long runs: the solved stencils assembled (vectorised; equal to the ghost rule for odd
        # d, tests/test_curves_creases.py); short odd runs: the ghost rule; short even: solved
        method = "assembled" if n >= 2 * d + 2 else ("ghost" if d % 2 else "solved")
    if method == "ghost":
        return _ghost_refinement(n, d, left, right)
    if method == "assembled":
        _check_run(n, d, left, right, "blocks")
        return _assembled_refinement(n, d, left, right)
    return sp.csr_matrix(_solved_refinement(n, d, left, right, "ghost" if d % 2 else "blocks"))


def runs_of(n: int, closed: bool, sharp: np.ndarray) -> list[tuple[list[int], str, str]]:
    """Cut a polygon at its sharp vertices: [(vertex indices, left type, right type)]."""
    idx = np.flatnonzero(sharp)
    if closed:
        if len(idx) == 0:
            return []
        out = []
        for a, v in enumerate(idx):
            w = idx[(a + 1) % len(idx)]
            if w <= v:
                w += n
            out.append(([k % n for k in range(v, w + 1)], CREASE, CREASE))
        return out
    cuts = [0] + [int(v) for v in idx if 0 < v < n - 1] + [n - 1]
    out = []
    for a in range(len(cuts) - 1):
        left = CREASE if (a > 0 or sharp[0]) else FREE
        right = CREASE if (a < len(cuts) - 2 or sharp[n - 1]) else FREE
        out.append((list(range(cuts[a], cuts[a + 1] + 1)), left, right))
    return out


def step_operator(n: int, d: int, closed: bool, sharp: np.ndarray) -> tuple[sp.csr_matrix, dict[int, int]]:
    """One step with the vertices of ``sharp`` (bool, n) infinitely sharp this step.

    Returns ``(A, child)``: A (n' x n) sparse, ``child[v]`` the new index of sharp vertex v.
    Closed polygons keep the uniform numbering (odd d: the child of P_i is point 2 i).
    """
    sharp = np.asarray(sharp, dtype=bool)
    if closed and not sharp.any():
        return uniform_subdivision(n, d, True), {}
    runs = runs_of(n, closed, sharp)
    blocks, child, offset = [], {}, 0
    for a, (verts, left, right) in enumerate(runs):
        T = run_refinement(len(verts), d, left, right).tocoo()
        first = 0 if a == 0 else 1  # the junction point belongs to the previous run
        last = T.shape[0] - (1 if (closed and a == len(runs) - 1) else 0)
        keep = (T.row >= first) & (T.row < last)
        blocks.append((T.row[keep] - first + offset, np.asarray(verts)[T.col[keep]], T.data[keep]))
        if left == CREASE and a == 0:
            child[verts[0]] = offset
        offset += last - first
        if right == CREASE and not (closed and a == len(runs) - 1):
            child[verts[-1]] = offset - 1
    rows = np.concatenate([b[0] for b in blocks])
    cols = np.concatenate([b[1] for b in blocks])
    vals = np.concatenate([b[2] for b in blocks])
    if closed and d % 2:
        # rotate so that the child of P_v0 is point 2 v0 (the uniform numbering)
        v0 = runs[0][0][0]
        rows = (rows + 2 * v0) % offset
        child = {v: (f + 2 * v0) % offset for v, f in child.items()}
    A = sp.coo_matrix((vals, (rows, cols)), shape=(offset, n)).tocsr()
    A.sum_duplicates()
    return A, child


def semi_sharp_step(
    n: int, d: int, closed: bool, sharpness: np.ndarray
) -> tuple[sp.csr_matrix, np.ndarray]:
    """One step of semi-sharp subdivision: ``(A, child_sharpness)``.

    Vertices with s >= 1 use the sharp rule and their child gets s - 1 (inf stays inf);
    0 < s < 1 blends: the new points are the mixture ``sum_A w_A (points with the vertices of A
    sharp)`` over the subsets A of the fractional vertices that interact (closer than d + 2),
    ``w_A = prod_(v in A) s_v prod_(v not in A) (1 - s_v)``, their children get 0.  For one
    fractional vertex at a time this is OpenSubdiv's ``s P_sharp + (1 - s) P_smooth``; the
    mixture over subsets keeps every stencil a convex combination (convex hull property).
    Why this rule for every odd d ([KSD] states the blend for cubics only): all later steps are
    smooth in both branches, so by linearity the limit is ``(1 - f) c_floor(s) + f c_ceil(s)``,
    the linear interpolation of the two neighbouring integer-sharpness limits; it adds no
    motion of its own (``vertex_limit_weights``, docs/curves.md).  A per-step blend needs
    an odd degree: for even d a sharp step gives 2n - 1 points where a smooth one gives 2n (the
    vertex stays one point instead of splitting in two), so there is no pair of points to blend;
    even d blends the two limits instead (``fractional_even_limit``), with no polygon after.
    """
    s = np.asarray(sharpness, dtype=np.float64)
    hard = s >= 1.0
    frac = np.flatnonzero((s > 0.0) & (s < 1.0))
    base, child = step_operator(n, d, closed, hard)
    A = base
    if len(frac):
        if d % 2 == 0:
            raise UnsupportedError(
                f"a step with fractional sharpness has no polygon at even degree {d} (only the exact limit: "
                "STEP, IGES, DXF)", f"vertex {int(frac[0])}")
        clusters: list[list[int]] = [[int(frac[0])]]
        for v in frac[1:]:
            if v - clusters[-1][-1] <= d + 2:
                clusters[-1].append(int(v))
            else:
                clusters.append([int(v)])
        if closed and len(clusters) > 1 and clusters[0][0] + n - clusters[-1][-1] <= d + 2:
            clusters[0] = clusters.pop() + clusters[0]
        A = base.copy()
        for C in clusters:
            if len(C) > 12:
                raise UnsupportedError("more than 12 fractionally sharp vertices close together", f"vertices {C[0]}..{C[-1]}")
            mix = None
            for k in range(len(C) + 1):
                for sub in combinations(C, k):
                    w = np.prod([s[v] if v in sub else 1.0 - s[v] for v in C])
                    mask = hard.copy()
                    mask[list(sub)] = True
                    op = step_operator(n, d, closed, mask)[0]
                    mix = w * op if mix is None else mix + w * op
            A = A + (mix - base)
        A = A.tocsr()
        A.eliminate_zeros()
    new_s = np.zeros(A.shape[0])
    for v, f in child.items():
        new_s[f] = s[v] - 1.0 if np.isfinite(s[v]) else np.inf
    return A, new_s


def limit_operator(n: int, d: int, closed: bool, sharp: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
    """The exact limit with the vertices of ``sharp`` infinitely sharp: ``(knots, W)``.

    One clamped B-spline of degree d, poles = W @ P: each run's clamped spline, joined at its
    sharp vertices with knot multiplicity d (C0 corner there, C^(d-1) elsewhere); a closed
    polygon without sharp vertices is its periodic uniform B-spline clamped at the seam.
    """
    sharp = np.asarray(sharp, dtype=bool)
    if closed and not sharp.any():
        knots, W = uniform_knots(n, d, True)
        kc, A = clamp_matrix(knots, d)
        return kc - kc[0], sp.csr_matrix(A @ W.toarray())
    runs = runs_of(n, closed, sharp)
    knots_all: list[np.ndarray] = []
    rows: list[np.ndarray] = []
    start = 0.0
    for a, (verts, left, right) in enumerate(runs):
        knots, M = run_space(len(verts), d, left, right)
        full = np.zeros((M.shape[0], n))
        np.add.at(full.T, np.asarray(verts), M.T)
        if a == 0:
            knots_all.append(knots + start)
            rows.append(full)
        else:
            knots_all.append(knots[d + 1 :] + start)  # drop the d+1 copies of the joint, keep d
            knots_all[-2] = knots_all[-2][:-1]
            rows.append(full[1:])  # the joint pole (the sharp vertex) is shared
        start += knots[-1]
    return np.concatenate(knots_all), sp.csr_matrix(np.vstack(rows))


def vertex_limit_weights(degree: int, sharpness: float, scheme=None) -> np.ndarray:
    """The limit point of an interior semi-sharp vertex as ``P_v + sum_i w_i (d+_i + d-_i)``.

    ``d+-_i = P_(v +- i) - P_v`` (i = 1 .. floor(d/2); the vertex alone, no other tag within
    d + 2 points); returns ``w`` (floor(d/2),).  "The limit at the vertex" is the limit point
    of the vertex's descendant: after k = s sharp steps the vertex is still P_v, its
    neighbours are the half-line crease rows ``creases.crease_scheme(d).T`` applied k times
    (mirrored on the other side), and then smooth subdivision takes that point to the value
    of the uniform B-spline at its centre: ``w_i(k) = sum_j l_j (T^k)_(j,i)``, l the centred
    B-spline values (for odd d the curve point at the vertex's parameter, for even d at the
    centre of the descendant's span, since the vertex has no knot of its own).  Fractional s
    (odd d only, ``semi_sharp_step``): each blended step is followed by smooth ones only, so
    by linearity the limit is ``(1 - f) w(floor s) + f w(ceil s)``.  s = inf gives w = 0.
    ``scheme``: another crease rule of the same structure (``creases.crease_scheme_solutions``)
    in place of ``crease_scheme(d)``, integer s only.
    """
    d = int(degree)
    s = float(sharpness)
    h = d // 2
    if math.isinf(s):
        return np.zeros(h)
    if s < 0 or math.isnan(s):
        raise ValueError(f"bad sharpness {sharpness!r}")
    lo = math.floor(s)
    f = s - lo
    if f and d % 2 == 0:
        raise UnsupportedError(f"fractional sharpness {s:g} needs an odd degree, not {d}")
    K = 4 * d + 8
    if scheme is None:
        T = run_refinement(K, d, CREASE, FREE, method="assembled").toarray()[:K, :K]
    else:  # the half-line matrix: the scheme's r rows, then the uniform stencils
        J = _J(d)
        i, j = np.mgrid[:K, :K]
        x = i - 2 * j + J
        T = np.where((x >= 0) & (x <= d + 1), np.vectorize(comb)(d + 1, np.clip(x, 0, d + 1)) / 2.0**d, 0.0)
        T[: scheme.r] = 0.0
        T[: scheme.r, : scheme.T.shape[1]] = scheme.T
    offs = np.arange(1, h + 1)
    knots = np.arange(d + 2, dtype=np.float64)
    from scipy.interpolate import BSpline  # here: scipy.interpolate costs every CLI start ~0.5 s

    centre = np.nan_to_num(BSpline.basis_element(knots, extrapolate=False)((d + 1) / 2 + offs))

    def at(k: int) -> np.ndarray:
        Tk = np.linalg.matrix_power(T, k)
        return centre @ Tk[1 : h + 1, 1 : h + 1]

    w = at(lo)
    return (1.0 - f) * w + f * at(lo + 1) if f else w


def fractional_even_limit(n: int, d: int, closed: bool, sharpness: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
    """Even d: the exact limit of a last step in which vertices have fractional sharpness.

    ``sharpness``: s >= 1 sharp this step (inf stays sharp in the limit), 0 < f < 1 the
    fractional vertices F, 0 smooth.  Returns ``(knots, W)`` in the units of the refined
    polygon (poles = W @ P), one clamped B-spline, C^(d-1) except at the infinitely sharp
    vertices.

    Why there is no per-step blend: a sharp step keeps the vertex as one point (its children
    are 2n - 1 points on a closed polygon), a smooth one splits it (2n), so the two refined
    polygons have no common numbering.  What is blended instead: both limits, on one knot
    structure.  With the vertex smooth this step, the limit c_0 has a knot t0 at the vertex
    between its two children that it does not need (c_0 is one polynomial over the coarse span
    [t0 - 1, t0 + 1], fine units), so c_0 is exactly a spline over the fine knots *without* t0:
    X, the smooth step's result expressed on the mesh of the sharp step (the same number of
    poles as the sharp step's limit c_1, the same knots except that this central span has
    length 2 instead of 1; the poles agree away from the vertex).  The blended curve takes the
    central span of length ``2 - f`` and the poles ``(1 - f) X + f c_1`` near each v in F
    (the sharp rule's share f, as OpenSubdiv's s P_sharp + (1 - s) P_smooth).  Properties:
    f -> 0 is c_0 and f -> 1 is c_1 exactly (knots and poles continuous in f); linear in the
    points; the poles are convex combinations (knot removal of a refined polygon and the
    crease rows are convex), so the curve lies in the polygon's hull; simple knots, so
    C^(d-1); only the poles whose support meets the central span change (locality).  The
    knot t0 is removed by least squares and the removal must be exact (1e-12): a fractional
    vertex too close to a sharp one (the crease blocks reach it) is refused, and so are two
    fractional vertices whose windows overlap.
    """
    s = np.asarray(sharpness, dtype=np.float64)
    frac = np.flatnonzero((s > 0) & (s < 1))
    hard = s >= 1
    if not len(frac):
        raise ValueError("no fractional vertex")
    A0, child0 = step_operator(n, d, closed, hard)
    A1, child1 = step_operator(n, d, closed, hard | ((s > 0) & (s < 1)))
    if closed and not (s == math.inf).any():
        # a periodic limit, clamped at a seam before fine point 0: put the seam at the same
        # place in both (the first child of the smooth vertex farthest from any tag)
        tagged = np.flatnonzero(s > 0)
        dist = np.min(np.abs((np.arange(n)[:, None] - tagged[None, :] + n // 2) % n - n // 2), axis=1)
        m = int(np.argmax(dist))
        if dist[m] < d + 2:
            raise UnsupportedError(f"a closed polygon with fractional sharpness at degree {d} needs a vertex {d + 2} "
                                   "points from every tag", f"vertex {int(frac[0])}")
        rolled = []
        for A in (A0, A1):
            top = np.flatnonzero(np.isclose(A[:, m].toarray().ravel(), A[:, m].max()))
            first = int(top[-1] if (len(top) == 2 and top[0] == 0 and top[1] == A.shape[0] - 1) else top[0])
            order = (np.arange(A.shape[0]) + first) % A.shape[0]
            rolled.append(A[order])
        A0, A1 = rolled
        child0, child1 = {}, {
            int(v): int(np.flatnonzero(np.isclose(A1[:, int(v)].toarray().ravel(), 1.0))[0]) for v in frac}
    inf0 = np.zeros(A0.shape[0], dtype=bool)
    inf1 = np.zeros(A1.shape[0], dtype=bool)
    for v in np.flatnonzero(s == math.inf):
        inf0[child0[int(v)]] = True
        inf1[child1[int(v)]] = True
    k0, W0 = limit_operator(A0.shape[0], d, closed, inf0)
    k1, W1 = limit_operator(A1.shape[0], d, closed, inf1)
    C0 = (W0 @ A0).toarray()
    C1 = (W1 @ A1).toarray()

    def greville(knots, p):
        return float(np.mean(knots[p + 1 : p + d + 1]))

    W0c, W1c = W0.tocsc(), W1.tocsc()
    remove, centres1 = [], []
    for v in frac:
        v = int(v)
        # the smooth step's two children of v: the two rows with v's largest weight
        kids = np.argsort(-A0[:, v].toarray().ravel(), kind="stable")[:2]
        g = [greville(k0, int(np.argmax(W0c[:, int(c)].toarray().ravel()))) for c in kids]
        t0 = 0.5 * (g[0] + g[1])
        if abs(abs(g[0] - g[1]) - 1.0) > 1e-9:
            raise UnsupportedError(f"fractional sharpness of vertex {v} too close to a sharp vertex or an end at degree {d}",
                                   f"vertex {v}")
        remove.append(t0)
        p1 = int(np.argmax(W1c[:, child1[v]].toarray().ravel()))
        centres1.append(greville(k1, p1))
    # c_0 without the knots t0 (exact knot removal, checked)
    kr = k0.copy()
    for t0 in remove:
        hit = np.flatnonzero(np.abs(kr - t0) < 1e-9)
        if len(hit) != 1:
            raise UnsupportedError(f"fractional sharpness too close to a sharp vertex at degree {d}", f"vertex {int(frac[0])}")
        kr = np.delete(kr, hit[0])
    ins, R = insert_knots_matrix(kr, d, remove, sparse=True)
    assert np.allclose(ins, k0)
    from scipy.sparse.linalg import spsolve  # here: only this rule needs it

    X = spsolve((R.T @ R).tocsc(), R.T @ C0)  # R is banded: the normal equations are cheap
    X = np.asarray(X).reshape(R.shape[1], C0.shape[1])
    if np.abs(R @ X - C0).max() > 1e-12 or len(kr) != len(k1):
        raise UnsupportedError(f"fractional sharpness of a vertex too close to a sharp vertex at degree {d}",
                               f"vertex {int(frac[0])}")
    shift = np.zeros_like(k1)
    for c in centres1:
        shift += k1 > c
    if np.abs(k1 + shift - kr).max() > 1e-9:
        raise RuntimeError("the smooth and sharp limits do not share a knot structure")
    # the poles that differ, each to its fractional vertex (by parameter, on c_1)
    diff = np.flatnonzero(np.abs(X - C1).max(axis=1) > 1e-14)
    g1 = np.array([greville(k1, int(p)) for p in diff])
    owner = np.argmin(np.abs(g1[:, None] - np.array(centres1)[None, :]), axis=1) if len(diff) else np.zeros(0, int)
    reach = d + 2
    if len(diff) and np.abs(g1 - np.array(centres1)[owner]).max() > reach:
        raise RuntimeError("a blended pole far from its fractional vertex")
    order = np.argsort(centres1)
    if closed and len(frac) > 1:
        span = float(k1[-1] - k1[0])
        gaps = np.diff(np.r_[np.array(centres1)[order], np.array(centres1)[order][0] + span])
    else:
        gaps = np.diff(np.array(centres1)[order])
    if len(gaps) and gaps.min() <= 2 * reach:
        raise UnsupportedError(f"fractional vertices closer than {reach} spans of the refined polygon at degree {d}",
                               f"vertex {int(frac[order[int(np.argmin(gaps))]])}")
    f = s[frac][owner]
    P = X.copy()
    P[diff] = (1.0 - f)[:, None] * X[diff] + f[:, None] * C1[diff]
    knots = k1.copy()
    for v_idx, c in enumerate(centres1):
        knots += (1.0 - s[frac[v_idx]]) * (k1 > c)
    P[np.abs(P) < 1e-15] = 0.0
    return knots, sp.csr_matrix(P)
