"""Invariants of the subdivision curves, checked with hypothesis: convex hull, locality of
creases and control vectors, linearity, C0 corners, monotone motion with sharpness."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from patching.curves.curve import Curve

ODD = st.sampled_from([3, 5, 7])
ANY = st.sampled_from([2, 3, 4, 5, 6, 7])
SHARPNESS = st.sampled_from([0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 2.5, math.inf])


@st.composite
def curves(draw, degrees=ANY):
    """Random polygons with sharp/semi-sharp vertices 2d + 2 apart and 2d + 2 away from the
    ends (so that every run is long enough for the even-degree rules)."""
    d = draw(degrees)
    closed = draw(st.booleans())
    n = draw(st.integers(5 * d + 8, 5 * d + 12))
    seed = draw(st.integers(0, 2**31))
    P = np.random.default_rng(seed).normal(size=(n, 2))
    corners = {}
    v = 2 * d + 2
    while v <= n - 1 - (2 * d + 2):
        s = draw(SHARPNESS)
        if d % 2 == 0 and 0 < s < math.inf:
            s = float(math.ceil(s))  # even degrees take integer sharpness only
        if s > 0:
            corners[v] = s
        v += draw(st.integers(2 * d + 2, 3 * d + 2))
    if not closed and draw(st.booleans()):
        corners[0] = corners[n - 1] = math.inf
    return Curve(P, d, closed, corners=corners)


@settings(max_examples=12, deadline=None)
@given(curves())
def test_limit_poles_are_convex_combinations(curve):
    """Convex hull: every pole of the exact limit is a convex combination of the polygon
    (rows of W non-negative, summing to one), so the curve lies in the polygon's hull."""
    knots, W, E = curve.limit_operator()
    W = W.toarray()
    assert W.min() > -1e-13  # round-off of the knot insertions
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-13)
    # and the evaluated curve in 2D lies inside the hull of the polygon
    from scipy.spatial import Delaunay

    hull = Delaunay(curve.points)
    t = np.linspace(*curve.limit().domain, 200)
    pts = curve.evaluate(t)
    inside = hull.find_simplex(pts, tol=1e-9) >= 0
    assert inside.all()


@settings(max_examples=20, deadline=None)
@given(ODD, st.integers(0, 2**31), SHARPNESS.filter(lambda s: s > 0), st.integers(0, 100))
def test_a_crease_changes_nothing_outside_d_plus_1_spans(d, seed, s, where):
    n = 3 * d + 8
    P = np.random.default_rng(seed).normal(size=(n, 3))
    v = 2 + where % (n - 4)
    ends = {0: math.inf, n - 1: math.inf}
    smooth = Curve(P, d, corners=ends)
    sharp = Curve(P, d, corners={**ends, v: s})
    t = np.linspace(0, n - 1, 20 * (n - 1) + 1)
    far = np.abs(t - v) >= (d + 1) / 2
    diff = np.abs(smooth.evaluate(t) - sharp.evaluate(t)).max(axis=1)
    assert diff[far].max() < 1e-13
    assert diff[~far].max() > 1e-6  # and it does change something near v


@settings(max_examples=20, deadline=None)
@given(ODD, st.integers(0, 2**31))
def test_sharp_vertex_is_a_C0_corner_at_the_control_point(d, seed):
    n = 3 * d + 6
    P = np.random.default_rng(seed).normal(size=(n, 3))
    v = n // 2
    c = Curve(P, d, corners={v: math.inf})
    lim = c.limit()
    values, counts = np.unique(lim.knots, return_counts=True)
    interior = counts[1:-1]
    assert sorted(interior)[-1] == d and (interior == d).sum() == 1  # C0 at one knot, C^(d-1) else
    u = values[1:-1][interior == d][0]
    assert np.allclose(lim.evaluate(u), P[v], atol=1e-13)
    from scipy.interpolate import BSpline

    db = BSpline(lim.knots, lim.poles, d).derivative()
    left, right = db(u - 1e-9), db(u + 1e-9)
    cosang = left @ right / np.linalg.norm(left) / np.linalg.norm(right)
    assert cosang < 1 - 1e-6  # a genuine corner for a generic polygon


@settings(max_examples=8, deadline=None)
@given(st.sampled_from([3, 5]), st.integers(0, 2**31))
def test_limit_at_the_vertex_moves_monotonically_with_sharpness(d, seed):
    """The limit point at a vertex approaches P_v monotonically as s grows (distance never
    increases), odd degrees (the vertex has a parameter).  Degree 7 is left out: there the limit after one sharp step can overshoot
    (docs/curves.md gives a polygon where the distance goes 0.026 -> 0.028 from s = 0 to 1)."""
    n = 3 * d + 6
    P = np.random.default_rng(seed).normal(size=(n, 2))
    v = n // 2
    ends = {0: math.inf, n - 1: math.inf}
    grid = [0, 0.25, 0.5, 0.75, 1, 1.5, 2, 2.5, 3, 4, math.inf]
    pts = np.array([Curve(P, d, corners={**ends, v: s} if s else ends).evaluate(float(v)) for s in grid])
    dist = np.linalg.norm(pts - P[v], axis=1)
    assert dist[-1] < 1e-13
    assert np.all(np.diff(dist) <= 1e-13)  # never moves away from the sharp position


@settings(max_examples=20, deadline=None)
@given(ANY, st.booleans(), st.integers(0, 2**31), st.sampled_from([1.0, 2.0, math.inf, 0.5]))
def test_control_vector_acts_linearly_and_locally(d, closed, seed, s):
    rng = np.random.default_rng(seed)
    n = 3 * d + 6
    P = rng.normal(size=(n, 2))
    v = n // 2
    V1, V2 = rng.normal(size=2), rng.normal(size=2)
    base = Curve(P, d, closed)
    c1 = Curve(P, d, closed, vectors={v: (V1, s)})
    c2 = Curve(P, d, closed, vectors={v: (V2, s)})
    c12 = Curve(P, d, closed, vectors={v: (V1 + 2 * V2, s)})
    t = np.linspace(*base.limit().domain, 40 * n + 1)
    f0, f1, f2, f12 = (c.evaluate(t) for c in (base, c1, c2, c12))
    assert np.abs((f12 - f0) - (f1 - f0) - 2 * (f2 - f0)).max() < 1e-12
    from patching.curves.control_vectors import crease_parameter

    # support of the crease function: floor(d/2) spans each side of its knot (within D + 1)
    lo = crease_parameter(v, n, d, closed) - _origin(base) - d // 2
    hi = lo + 2 * (d // 2)
    assert hi - lo <= d + 1
    outside = (t < lo - 1e-9) | (t > hi + 1e-9)
    assert np.abs(f1 - f0)[outside].max() < 1e-13
    assert np.abs(f1 - f0)[~outside].max() > 1e-8


def _origin(curve: Curve) -> float:
    """The parameter, on uniform_knots, where the exported domain starts."""
    from patching.curves.uniform import uniform_knots

    return float(uniform_knots(len(curve.points), curve.degree, curve.closed)[0][curve.degree])
