"""The subdivision curve object: polygon, degree, sharp vertices, control vectors.

``Curve(points, degree, closed, corners={v: s}, vectors={v: (V, s)})``; ``refine(k)`` gives the
curve after k subdivision steps (a Curve again, sharpness decremented), ``limit()`` the exact
limit as one clamped B-spline (knots, poles, degree), ``evaluate(t)`` points on it.

The limit is exact: after ``L = ceil(max finite sharpness)`` steps every remaining crease is
infinitely sharp, and the curve is then a B-spline of the refined polygon with knot
multiplicity d at the sharp vertices (``runs.limit_operator``) or at the crease knots of the
control vectors (``control_vectors.vector_limit``).  The parameter is measured in spans of the
original polygon (the refined knots divided by 2^L).

Rules for the tags:

- an end vertex of an open polygon with sharpness > 0 is a sharp end (the curve starts
  there, [KSD] sec. 3.1 end conditions); without a tag the curve covers the n - d full spans;
- fractional sharpness: odd d blends the points of each step (``runs.semi_sharp_step``); even
  d has no per-step blend (the sharp and smooth steps give different point counts: the sharp
  vertex stays one point on a knot, a smooth one splits in two), so the step where the
  sharpness is fractional blends the two exact limits on one knot structure
  (``runs.fractional_even_limit``); before the curve's last level, that blend of v's window
  is spliced into the sharp branch's limit (``_early_fractional_limit_operator``).
  ``refine`` cannot go through the first fractional step (there is no polygon after it);
  ``limit`` and the B-spline writers can;
- corners (end and interior, any sharpness) and control vectors compose: the curve is
  ``sum_i B_i P_i + sum_j C^_j V_j`` with B_i the basis of the corner scheme and C^_j the
  crease function of [KSD] Table 1 at the vector.  A step is the corner step of the points plus
  the vectors' masks (``control_vectors.vector_step``) put on the corner step's points with the
  same (uniform) stencils; the limit inserts the vectors' crease knots into the corner limit.
  This is exact superposition only where the vector's fine B-splines are uniform ones of the
  corner scheme, so a vector needs ``VECTOR_CLEARANCE[d]`` polygon edges between its vertex and
  every tagged vertex (sharp end included); closer, and on a tagged vertex, it is refused in one
  line naming the vertex.  At even degree a fractional corner (whose last step leaves no
  polygon) does not take control vectors either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError, TagError, UnsupportedError
from .control_vectors import crease_parameter, vector_limit, vector_step, vectors_on_limit
from .knots import insert_knots_matrix
from .runs import fractional_even_limit, limit_operator, semi_sharp_step
from .uniform import MAX_DEGREE, MIN_DEGREE

__all__ = ["VECTOR_CLEARANCE", "Curve", "BSplineCurve", "ModifiedQuinticCurve", "ModifiedQuinticFit", "modified_quintic_limit"]


@dataclass(frozen=True)
class BSplineCurve:
    """A clamped B-spline: ``knots`` (n + d + 1,), ``poles`` (n, dim), ``degree``."""

    knots: np.ndarray
    poles: np.ndarray
    degree: int

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[0]), float(self.knots[-1])

    def evaluate(self, t) -> np.ndarray:
        """Points at parameters ``t`` (scalar or array) in ``domain``."""
        from scipy.interpolate import BSpline  # here: scipy.interpolate costs every CLI start ~0.5 s

        return BSpline(self.knots, self.poles, self.degree, extrapolate=False)(np.clip(t, *self.domain))

    def split_at_sharp(self) -> list["BSplineCurve"]:
        """One clamped B-spline per smooth run: split at the interior knots of multiplicity d
        (the sharp vertices, where the pole before the knot group is the corner point)."""
        d = self.degree
        values, counts = np.unique(self.knots, return_counts=True)
        cuts = [(v, int(np.searchsorted(self.knots, v, side="left")) - 1) for v, c in zip(values[1:-1], counts[1:-1]) if c >= d]
        bounds = [(values[0], 0)] + cuts + [(values[-1], len(self.poles) - 1)]
        out = []
        for (a, pa), (b, pb) in zip(bounds[:-1], bounds[1:]):
            inner = self.knots[(self.knots > a) & (self.knots < b)]
            out.append(BSplineCurve(np.r_[np.full(d + 1, a), inner, np.full(d + 1, b)], self.poles[pa : pb + 1], d))
        return out


class Curve:
    """A subdivision curve of degree 2..7 with semi-sharp vertices or control vectors ([KSD])."""

    def __init__(
        self,
        points,
        degree: int = 3,
        closed: bool = False,
        corners: dict[int, float] | None = None,
        vectors: dict[int, tuple] | None = None,
        name: str = "curve",
        *,
        _sharpness: np.ndarray | None = None,
        _vector_state: tuple | None = None,
    ) -> None:
        P = np.asarray(points, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] not in (2, 3):
            raise MeshError(f"points must be an (n, 2) or (n, 3) array, not {P.shape}")
        if not np.isfinite(P).all():
            raise MeshError("non-finite control point", f"vertex {int(np.argwhere(~np.isfinite(P))[0, 0])}")
        n = len(P)
        if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
            raise UnsupportedError(f"degree must be an integer, not {degree!r}")
        if not MIN_DEGREE <= degree <= MAX_DEGREE:
            raise UnsupportedError(f"degree {degree} is not supported ({MIN_DEGREE}..{MAX_DEGREE})")
        if n < 2:
            raise MeshError(f"a control polygon of {n} vertex needs at least 2")
        self.points = P
        self.degree = int(degree)
        self.closed = bool(closed)
        self.name = name
        d = self.degree
        if _sharpness is not None:
            s = np.asarray(_sharpness, dtype=np.float64)
        else:
            s = np.zeros(n)
            for v, value in (corners or {}).items():
                if not 0 <= int(v) < n:
                    raise TagError(f"corner on vertex {v}, which is not on the polygon ({n} vertices)")
                value = float(value)
                if math.isnan(value):
                    raise TagError(f"sharpness of vertex {v} is NaN")
                if value < 0:
                    raise TagError(f"negative sharpness {value} of vertex {v}")
                s[int(v)] = math.inf if value >= 10 else value
            if not closed:
                for end in (0, n - 1):
                    if s[end] > 0:
                        s[end] = math.inf
        self.sharpness = s
        self._vverts: list[int] | None = None  # vertices of the vectors, when corners are present too
        if _vector_state is not None:
            self._vparams, self._vectors, self._vsharp = _vector_state[:3]
            self._vverts = _vector_state[3] if len(_vector_state) > 3 else None
        else:
            params, vecs, vs = [], [], []
            for v, spec in (vectors or {}).items():
                if not 0 <= int(v) < n:
                    raise TagError(f"control vector on vertex {v}, which is not on the polygon ({n} vertices)")
                if isinstance(spec, tuple) and len(spec) == 2 and np.ndim(spec[0]) == 1:
                    vec, value = spec
                else:
                    vec, value = spec, math.inf
                vec = np.asarray(vec, dtype=np.float64)[: P.shape[1]]
                value = float(value)
                if math.isnan(value) or value < 0:
                    raise TagError(f"bad sharpness {value} of the control vector at vertex {v}")
                if not np.isfinite(vec).all():
                    raise TagError(f"non-finite control vector at vertex {v}")
                params.append(crease_parameter(int(v), n, d, self.closed))
                vecs.append(vec)
                vs.append(math.inf if value >= 10 else value)
            self._vparams = np.array(params, dtype=np.float64)
            self._vectors = np.array(vecs, dtype=np.float64).reshape(-1, P.shape[1])
            self._vsharp = np.array(vs, dtype=np.float64)
        interior = s.copy()
        if not closed:
            interior[[0, n - 1]] = 0
        if _vector_state is None and len(self._vparams) and (s > 0).any():
            self._vverts = _check_clearance(n, d, self.closed, s, [int(v) for v in (vectors or {})])
        if not closed and n <= d and not (s[0] > 0 or s[-1] > 0):
            raise MeshError(f"an open polygon of degree {d} without sharp ends needs more than {d} vertices, not {n}")

    # ------------------------------------------------------------------ refinement
    def _step(self):
        n, d = len(self.points), self.degree
        if self._vverts is not None and len(self._vverts):
            return self._composed_step()
        if len(self._vparams):
            A, C, H, u2, s2 = vector_step(n, d, self.closed, self._vparams, self._vsharp)
            P2 = A @ self.points + C @ self._vectors
            return A, C, H, P2, self.sharpness_after(A.shape[0]), (u2, H @ self._vectors, s2)
        A, s2 = semi_sharp_step(n, d, self.closed, self.sharpness)
        return A, None, None, A @ self.points, s2, (self._vparams, self._vectors, self._vsharp, None)

    def _composed_step(self):
        """Corners and vectors: the corner step of the points, the vectors' masks (computed on
        the uniform step) moved to the corner step's points with the same stencils."""
        n, d, closed = len(self.points), self.degree, self.closed
        A, s2 = semi_sharp_step(n, d, closed, self.sharpness)
        params = np.array([crease_parameter(v, n, d, closed) for v in self._vverts])
        Au, Cu, H, u2, vs2 = vector_step(n, d, closed, params, self._vsharp)
        Ac, Au = A.tocsc(), Au.tocsr()
        Au.sort_indices()

        def same_row(f: int, v: int) -> int:
            cols = Au.indices[Au.indptr[f] : Au.indptr[f + 1]]
            vals = Au.data[Au.indptr[f] : Au.indptr[f + 1]]
            for r in Ac.indices[Ac.indptr[cols[0]] : Ac.indptr[cols[0] + 1]]:
                row = A.getrow(r)
                row.sort_indices()
                if np.array_equal(row.indices, cols) and np.allclose(row.data, vals, rtol=0, atol=1e-12):
                    return int(r)
            raise UnsupportedError(f"control vector too close to a tagged vertex at degree {d}", f"vertex {v}")

        Cu = Cu.tocoo()
        rows = [same_row(int(f), self._vverts[int(e)]) for f, e in zip(Cu.row, Cu.col)]
        C = sp.coo_matrix((Cu.data, (rows, Cu.col)), shape=(A.shape[0], Cu.shape[1])).tocsr()
        n2u = Au.shape[0]
        kept = H.tocoo().col
        verts = [same_row(_vertex_at(float(u), n2u, d, closed), self._vverts[int(e)]) for u, e in zip(u2, kept)]
        P2 = A @ self.points + C @ self._vectors
        return A, C, H, P2, s2, (u2, H @ self._vectors, vs2, verts)

    def sharpness_after(self, n2: int) -> np.ndarray:
        s = np.zeros(n2)
        if not self.closed:
            s[0], s[-1] = self.sharpness[0], self.sharpness[-1]
        return s

    def refine(self, k: int = 1) -> "Curve":
        """The curve after ``k`` subdivision steps (same limit; sharpness decremented)."""
        if self._fractional_even and int(k) >= self._first_fractional_level:
            L = self._first_fractional_level
            raise UnsupportedError(
                f"at even degree {self.degree} step {L} blends two limits (fractional sharpness) and leaves no polygon: "
                f"take at most {L - 1} steps (-n {L - 1}), or write the exact B-spline (STEP, IGES, DXF)"
            )
        c = self
        for _ in range(int(k)):
            A, C, H, P2, s2, vstate = c._step()
            c = Curve(P2, c.degree, c.closed, name=c.name, _sharpness=s2, _vector_state=vstate)
        return c

    def _run(self, k: int):
        """k steps at once: (A, C, H, curve) with points = A P + C V, vectors = H V."""
        n, m = len(self.points), len(self._vparams)
        A_tot = sp.identity(n, format="csr")
        C_tot = sp.csr_matrix((n, m))
        H_tot = sp.identity(m, format="csr")
        c = self
        for _ in range(int(k)):
            A, C, H, P2, s2, vstate = c._step()
            C_tot = A @ C_tot + (C @ H_tot if C is not None else 0)
            A_tot = A @ A_tot
            if H is not None:
                H_tot = H @ H_tot
            c = Curve(P2, c.degree, c.closed, name=c.name, _sharpness=s2, _vector_state=vstate)
        return A_tot.tocsr(), sp.csr_matrix(C_tot), sp.csr_matrix(H_tot), c

    def operators(self, k: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """``(A, C)`` with points after k steps = A @ points + C @ vectors (sparse)."""
        A, C, _, _ = self._run(k)
        return A, C

    @property
    def steps_to_exact(self) -> int:
        """L = ceil(largest finite sharpness): steps after which the limit is a B-spline."""
        finite = [x for x in np.r_[self.sharpness, self._vsharp] if 0 < x < math.inf]
        return int(math.ceil(max(finite))) if finite else 0

    @property
    def _fractional_even(self) -> bool:
        s = self.sharpness
        return self.degree % 2 == 0 and bool(np.any((s > 0) & np.isfinite(s) & (s != np.floor(s))))

    @property
    def _first_fractional_level(self) -> int:
        """Even d: the first step with a fractional sharpness (it leaves no polygon)."""
        s = self.sharpness
        frac = s[(s > 0) & np.isfinite(s) & (s != np.floor(s))]
        return int(math.ceil(frac.min())) if len(frac) else self.steps_to_exact

    def limit_operator(self) -> tuple[np.ndarray, sp.csr_matrix, sp.csr_matrix]:
        """``(knots, W, E)``: the exact limit's poles = W @ points + E @ vectors (sparse)."""
        L = self.steps_to_exact
        if self._fractional_even and self._first_fractional_level < L:
            return self._early_fractional_limit_operator()
        if self._fractional_even:  # the last step blends two limits (runs.fractional_even_limit)
            A, C, H, c = self._run(L - 1)
            knots, W = fractional_even_limit(len(c.points), c.degree, c.closed, c.sharpness)
            return knots / 2.0**L, (W @ A).tocsr(), sp.csr_matrix(W @ C)
        A, C, H, c = self._run(L)
        n = len(c.points)
        sharp = c.sharpness == math.inf
        if c._vverts is not None and len(c._vverts) and sharp.any():
            # corners and vectors: the crease knots inserted into the corner limit
            knots, W0 = limit_operator(n, c.degree, c.closed, sharp)
            knots, W, E = vectors_on_limit(knots, W0, c.degree, c._vverts)
            return knots / 2.0**L, (W @ A).tocsr(), (W @ C + E @ H).tocsr()
        if len(c._vparams):
            if c._vverts is not None:  # no corner left: the uniform curve's parameters
                c._vparams = np.array([crease_parameter(v, n, c.degree, c.closed) for v in c._vverts])
            knots, W, E = vector_limit(n, c.degree, c.closed, c._vparams)
            return knots / 2.0**L, (W @ A).tocsr(), (W @ C + E @ H).tocsr()
        knots, W = limit_operator(n, c.degree, c.closed, sharp)
        # vectors that all died before level L live on in C
        return knots / 2.0**L, (W @ A).tocsr(), sp.csr_matrix(W @ C)

    def _early_fractional_limit_operator(self) -> tuple[np.ndarray, sp.csr_matrix, sp.csr_matrix]:
        """Even d, a fractional sharpness s_v whose step k = ceil(s_v) comes before the curve's
        last level L: the sharp branch's limit c_1 (s_v raised to k, exact after L steps) with
        the neighbourhood of v replaced by the blend of the last-step rule
        (``runs.fractional_even_limit``) applied to v's window of the level-(k - 1) polygon.

        Why this is exact and well defined: the two branches (v smooth or sharp at step k) have
        the same level-(k - 1) polygon; from step k on they differ only near v, where no other
        tag reaches (checked), so both limits are, near v, the limits of that window alone, and
        away from v they are the same curve (the right part shifted by (1 - f) 2^-k, the
        longer central span).  The window's blend is refined to level L by midpoint knot
        insertion and spliced into c_1 where their B-splines coincide: d + 1 poles on each side
        must have equal operator rows and knots (checked to 1e-12, else refused).  With the
        fractional step last this is the same construction as ``fractional_even_limit`` on the
        whole polygon, and f -> 0, 1 give the integer-sharpness curves.  Refused: a window that
        meets another tag, an end or the closed polygon's seam; windows that overlap.
        """
        d, closed = self.degree, self.closed
        s = self.sharpness
        L = self.steps_to_exact
        frac = [int(v) for v in np.flatnonzero((s > 0) & np.isfinite(s) & (s != np.floor(s)))]
        early = [v for v in frac if math.ceil(s[v]) < L]
        s1 = s.copy()
        s1[early] = np.ceil(s1[early])
        knots, W, _ = Curve(self.points, d, closed, _sharpness=s1).limit_operator()
        W = W.toarray()
        R = d + 2  # window half-width in points of the level-(k - 1) polygon (measured: d = 2, 4, 6 need 3, 6, 8)
        pieces = []
        for v in early:
            k = int(math.ceil(s[v]))
            f = s[v] - math.floor(s[v])
            sk = s1.copy()
            sk[v] = 1.0 + (k - 1)  # sharp through step k - 1; at level k - 1 its child has 1
            A, _, _, c = Curve(self.points, d, closed, _sharpness=sk)._run(k - 1)
            # v's descendant: the point whose sharpness is 1 here and that the vertex row feeds most
            cand = np.flatnonzero(c.sharpness == 1.0)
            col = A.tocsc()[:, v].toarray().ravel()
            u = int(cand[np.argmax(col[cand])]) if len(cand) else -1
            m = len(c.points)
            if u < 0 or (closed and 2 * R + 1 > m):
                raise UnsupportedError(f"fractional sharpness {s[v]:g} at even degree {d} on too short a polygon "
                                       "before the curve's last level", f"vertex {v}")
            # the window; an open polygon's end inside it stays the window's end, with its rule
            first, last = (u - R, u + R) if closed else (max(u - R, 0), min(u + R, m - 1))
            idx = np.arange(first, last + 1) % m
            sl = np.zeros(len(idx))
            sl[u - first] = f
            clipped = (not closed and first == 0, not closed and last == m - 1)
            if clipped[0]:
                sl[0] = c.sharpness[0]
            if clipped[1]:
                sl[-1] = c.sharpness[m - 1]
            others = [int(i) for i in idx if i != u and c.sharpness[i] > 0
                      and not (clipped[0] and i == 0) and not (clipped[1] and i == m - 1)]
            if others:
                raise UnsupportedError(f"fractional sharpness {s[v]:g} at even degree {d} too close to another tag "
                                       "before the curve's last level", f"vertex {v}")
            try:
                kl, Wl = fractional_even_limit(len(idx), d, False, sl)
            except UnsupportedError:
                raise UnsupportedError(f"fractional sharpness {s[v]:g} at even degree {d} too close to an end "
                                       "before the curve's last level", f"vertex {v}") from None
            for _ in range(L - k):  # to level L: the midpoint of every span
                mids = [(a + b) / 2 for a, b in zip(kl[:-1], kl[1:]) if b > a]
                kl, Ins = insert_knots_matrix(kl, d, mids, sparse=True)
                Wl = Ins @ Wl
            B = (Wl @ A[idx]).toarray()
            pieces.append((v, kl / 2.0**k, B, clipped))
        # splice right to left, so that the left indices stay valid
        spliced = []
        for v, kb, B, clipped in pieces:
            lo = 0 if clipped[0] else d + 1
            hi = len(B) - d - 1 if clipped[1] else len(B) - 2 * d - 2

            def match(p: int) -> int:
                err = np.abs(W - B[p]).max(axis=1)
                q = int(np.argmin(err))
                if err[q] > 1e-12 or np.abs(W[q : q + d + 1] - B[p : p + d + 1]).max() > 1e-12:
                    raise UnsupportedError(f"fractional sharpness {s[v]:g} at even degree {d}: its window does not "
                                           "join the curve (another tag nearby?)", f"vertex {v}")
                return q - p

            spliced.append((match(lo), match(hi), v, kb, B, lo, hi))
        spliced.sort(key=lambda x: x[0])
        for (o, o2, v, kb, B, lo, hi), nxt in zip(spliced[:-1], spliced[1:]):
            if o2 + hi > nxt[0] + nxt[5]:
                raise UnsupportedError(f"fractional sharpness at even degree {d}: the windows of vertices {v} and "
                                       f"{nxt[2]} overlap before the curve's last level", f"vertex {nxt[2]}")
        spliced.reverse()
        for o, o2, v, kb, B, lo, hi in spliced:
            a = knots[o + lo] - kb[lo]
            if not np.allclose(kb[lo : lo + 2 * d + 2] + a, knots[o + lo : o + lo + 2 * d + 2], atol=1e-12):
                raise RuntimeError("the fractional window's knots do not match the curve's")
            shift = kb[hi + d + 1] + a - knots[o2 + hi + d + 1]
            if not np.allclose(kb[hi : hi + 2 * d + 2] + a, knots[o2 + hi : o2 + hi + 2 * d + 2] + shift, atol=1e-12):
                raise RuntimeError("the fractional window's knots do not match the curve's on its right")
            W = np.vstack([W[: o + lo], B[lo:hi], W[o2 + hi :]])
            knots = np.r_[knots[: o + lo], kb[lo : hi + d + 1] + a, knots[o2 + hi + d + 1 :] + shift]
        W[np.abs(W) < 1e-15] = 0.0
        return knots, sp.csr_matrix(W), sp.csr_matrix((W.shape[0], len(self._vparams)))

    def limit(self) -> BSplineCurve:
        """The exact limit curve: one clamped B-spline of degree d (multiple knots at creases)."""
        knots, W, E = self.limit_operator()
        poles = W @ self.points
        if len(self._vparams):
            poles = poles + E @ self._vectors
        return BSplineCurve(knots, np.asarray(poles), self.degree)

    def evaluate(self, t) -> np.ndarray:
        """Points of the limit curve at ``t`` (spans of the original polygon, from 0)."""
        return self.limit().evaluate(t)

    @property
    def vectors(self) -> np.ndarray:
        return self._vectors


#: polygon edges needed between a control vector's vertex and any tagged vertex (sharp ends
#: too), per degree: from there on the vector's fine points have uniform stencils in the corner
#: step at every level and its crease knot sits in uniform unit spans of the corner limit, so
#: the result is exactly the superposition (tests/test_curves_control_vectors.py checks it at
#: this distance on both sides, s in {1, 2, 2.5, inf}, open and closed).  Measured: one edge
#: less fails one of the two checks for some sharpness (it never gives a wrong curve: those
#: checks refuse).  Odd d: (d + 3) / 2, even d: d / 2 + 3 (the vector sits between v and v + 1).
VECTOR_CLEARANCE = {d: (d + 3) // 2 if d % 2 else d // 2 + 3 for d in range(MIN_DEGREE, MAX_DEGREE + 1)}


def _check_clearance(n: int, d: int, closed: bool, s: np.ndarray, verts: list[int]) -> list[int]:
    """Refuse a vector on or too near a tagged vertex (one line naming it); the vertices."""
    tagged = np.flatnonzero(s > 0)
    frac = tagged[np.isfinite(s[tagged]) & (s[tagged] != np.floor(s[tagged]))]
    for v in verts:
        if s[v] > 0:
            raise TagError(f"vertex {v} has both a corner tag and a control vector (give it one of the two)")
        if d % 2 == 0 and len(frac):
            raise UnsupportedError(f"control vectors with fractional corner sharpness at even degree {d} are not "
                                   f"supported (its last step leaves no polygon)", f"vertex {int(frac[0])}")
        gap = np.abs(tagged - v)
        if closed:
            gap = np.minimum(gap, n - gap)
        if len(gap) and gap.min() < VECTOR_CLEARANCE[d]:
            u = int(tagged[int(np.argmin(gap))])
            raise UnsupportedError(
                f"control vector {int(gap.min())} edges from the tagged vertex {u}: degree {d} needs "
                f"{VECTOR_CLEARANCE[d]} (its crease function would meet the corner rule)", f"vertex {v}")
    return list(verts)


def _vertex_at(u: float, n: int, d: int, closed: bool) -> int:
    """The vertex whose crease parameter (``control_vectors.crease_parameter``) is u."""
    off = 0.0 if d % 2 else 0.5
    return int(round(u - off)) % n if closed else int(round(u - off + (d - 1) / 2))


@dataclass(frozen=True)
class ModifiedQuinticFit:
    """The result of ``modified_quintic_limit``: the B-spline, the steps taken and the error
    bound measured against the refined T~5 polygon."""

    curve: BSplineCurve
    steps: int
    error: float


def modified_quintic_limit(
    points, closed: bool = False, corners: dict[int, float] | None = None, tolerance: float = 1e-6,
    max_steps: int = 14, check_steps: int = 5,
) -> ModifiedQuinticFit:
    """The modified quintic T~5 ([KSD] sec. 3.2.2, eq. (7)) as one quintic B-spline within
    ``tolerance`` (absolute, the polygon's units).

    T~5 has infinitely many polynomial pieces near a crease, so there is no exact B-spline.
    After k steps of T~5 (``creases.modified_quintic_operator``) the polygon P_k is taken as the
    control polygon of the exact quintic crease scheme T5 ([KSD] eq. (5); the same sharp
    vertices, all infinitely sharp once the semi-sharp ones are used up), whose limit is a
    B-spline (``Curve.limit``).  Away from the creases both schemes are uniform, so the two
    limits differ only in a neighbourhood of each crease that halves with every step.  The
    check: ``check_steps`` more steps of T~5 on P_k and of T5 on the same P_k give two polygons
    with the same numbering (the child of P_i is point 2 i in both); their largest pointwise
    distance is the error (as the steps grow it tends to the largest distance between the two
    limits at equal parameters, an upper bound of the Hausdorff distance).  k grows until the
    error is within ``tolerance``; UnsupportedError after ``max_steps``.
    """
    from .creases import modified_quintic_operator

    P = np.asarray(points, dtype=np.float64)
    n = len(P)
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise UnsupportedError(f"the tolerance must be a positive number, not {tolerance!r}")
    ends = {} if closed else {0: math.inf, n - 1: math.inf}  # T~5's open ends are sharp
    probe = Curve(P, 5, closed, corners={**(corners or {}), **ends})  # the tags' checks
    s = probe.sharpness.copy()
    if not closed:
        s[[0, n - 1]] = math.inf
    for k in range(max_steps + 1):
        if not np.any((s > 0) & np.isfinite(s)):
            sharp = {int(i): math.inf for i in np.flatnonzero(s == math.inf)}
            candidate = Curve(P, 5, closed, corners=sharp)
            Q5 = candidate.refine(check_steps).points
            Qt, st = P, s
            for _ in range(check_steps):
                A, st = modified_quintic_operator(len(Qt), closed, st)
                Qt = A @ Qt
            error = float(np.linalg.norm(Qt - Q5, axis=1).max())
            if error <= tolerance:
                lim = candidate.limit()
                return ModifiedQuinticFit(BSplineCurve(lim.knots / 2.0**k, lim.poles, 5), k, error)
        A, s = modified_quintic_operator(len(P), closed, s)
        P = A @ P
    raise UnsupportedError(
        f"the modified quintic did not come within {tolerance:g} in {max_steps} steps (error {error:.3g}): "
        "give a larger --tolerance"
    )


class ModifiedQuinticCurve:
    """A T~5 curve ([KSD] eq. (7)) with the interface the writers use: ``refine(k)`` (the T~5
    polygon), ``limit()`` (``modified_quintic_limit`` within ``tolerance``), ``evaluate``.
    ``tolerance`` None: 1e-6 of the polygon's bounding-box diagonal."""

    degree = 5

    def __init__(self, points, closed: bool = False, corners: dict[int, float] | None = None,
                 tolerance: float | None = None, name: str = "curve", *, _sharpness=None) -> None:
        n = len(np.asarray(points))
        ends = {} if closed else {0: math.inf, n - 1: math.inf}  # T~5's open ends are sharp
        probe = Curve(points, 5, closed, corners={**(corners or {}), **ends}, name=name, _sharpness=_sharpness)
        self.points, self.closed, self.name = probe.points, probe.closed, name
        self.sharpness = probe.sharpness
        if tolerance is None:
            diag = float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))
            tolerance = 1e-6 * (diag or 1.0)
        self.tolerance = tolerance
        self._fit: ModifiedQuinticFit | None = None

    def refine(self, k: int = 1) -> "ModifiedQuinticCurve":
        from .creases import modified_quintic_operator

        P, s = self.points, self.sharpness.copy()
        for _ in range(int(k)):
            A, s = modified_quintic_operator(len(P), self.closed, s)
            P = A @ P
        return ModifiedQuinticCurve(P, self.closed, name=self.name, tolerance=self.tolerance, _sharpness=s)

    def fit(self) -> ModifiedQuinticFit:
        if self._fit is None:
            corners = {int(i): float(x) for i, x in enumerate(self.sharpness) if x > 0}
            self._fit = modified_quintic_limit(self.points, self.closed, corners, self.tolerance)
        return self._fit

    def limit(self) -> BSplineCurve:
        """A quintic B-spline within ``tolerance`` of the T~5 limit (not exact: see
        ``modified_quintic_limit``)."""
        return self.fit().curve

    def evaluate(self, t) -> np.ndarray:
        return self.limit().evaluate(t)
