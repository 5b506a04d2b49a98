"""Invariants of the subdivision curves, checked with hypothesis: convex hull, locality of
creases and control vectors, linearity, C0 corners, monotone motion with sharpness."""

from __future__ import annotations

import math

import numpy as np
import pytest
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
        if s > 0:
            corners[v] = s
        v += draw(st.integers(2 * d + 2, 3 * d + 2))
    finite = [s for s in corners.values() if s < math.inf]
    if d % 2 == 0 and finite:  # even d: a fractional sharpness must be at the last level
        L = math.ceil(max(finite))
        corners = {k: (float(L) if s < math.inf and s != int(s) and math.ceil(s) < L else s) for k, s in corners.items()}
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


def _vertex_limit(d: int, P: np.ndarray, v: int, s: float) -> np.ndarray:
    """The limit point of vertex v's descendant, read off the curve itself: odd d the exact
    limit at the vertex's parameter (open polygon with sharp ends: parameter v); even d
    (integer s) the refined polygon after s steps, child of v = last point of the left run,
    then the centred B-spline values (the uniform limit stencil), independent of the runs'
    parameterisation."""
    n = len(P)
    ends = {0: math.inf, n - 1: math.inf}
    c = Curve(P, d, corners={**ends, v: s} if s else ends)
    if d % 2:
        return c.evaluate(float(v))
    if s == math.inf:  # the point at the interior knot of multiplicity d
        lim = c.limit()
        values, counts = np.unique(lim.knots, return_counts=True)
        return lim.evaluate(values[1:-1][counts[1:-1] == d][0])
    from scipy.interpolate import BSpline

    from patching.curves.runs import CREASE, run_refined_size

    k = int(s)
    m = v + 1
    for _ in range(k):
        m = run_refined_size(m, d, CREASE, CREASE)
    Q = c.refine(k).points
    offs = np.arange(-(d // 2), d // 2 + 1)
    centre = np.nan_to_num(BSpline.basis_element(np.arange(d + 2.0), extrapolate=False)((d + 1) / 2 + offs))
    return centre @ Q[m - 1 + offs]


@settings(max_examples=6, deadline=None)
@given(ANY, st.integers(0, 2**31), st.sampled_from([0.0, 0.5, 1.0, 2.0, 2.5, 3.0]))
def test_vertex_limit_weights_are_the_curves_limit_at_the_vertex(d, seed, s):
    """runs.vertex_limit_weights against the curve: P_v + sum_i w_i (d+_i + d-_i)."""
    from patching.curves.runs import vertex_limit_weights

    if d % 2 == 0:
        s = float(math.floor(s))
    n = 3 * d + 6
    P = np.random.default_rng(seed).normal(size=(n, 2))
    v = n // 2
    w = vertex_limit_weights(d, s)
    i = np.arange(1, d // 2 + 1)
    expect = P[v] + w @ (P[v + i] + P[v - i] - 2 * P[v])
    assert np.abs(_vertex_limit(d, P, v, s) - expect).max() < 1e-12


def test_vertex_limit_weights_are_the_hand_derived_fractions():
    """s = 0: the centred B-spline values; s = 1: one step of the paper's T_4 / T_5, then the
    limit stencil (worked by hand: d = 5, rows (17, 14, 1)/32, (6, 20, 6)/32 and stencil
    (1, 26, 66, 26, 1)/120 give 384/3840 and 32/3840; d = 4, rows (10, 5, 1)/16,
    (2, 9, 5)/16 of [KSD]'s T_4 and stencil (1, 76, 230, 76, 1)/384 give 389/6144, 81/6144)."""
    from patching.curves.runs import vertex_limit_weights

    assert np.allclose(vertex_limit_weights(5, 0), [26 / 120, 1 / 120], atol=1e-15)
    assert np.allclose(vertex_limit_weights(5, 1), [1 / 10, 1 / 120], atol=1e-15)
    assert np.allclose(vertex_limit_weights(4, 0), [76 / 384, 1 / 384], atol=1e-15)
    assert np.allclose(vertex_limit_weights(4, 1), [389 / 6144, 81 / 6144], atol=1e-15)
    assert np.allclose(vertex_limit_weights(3, 2.5), [0.5 / 24 + 0.5 / 48], atol=1e-15)


@pytest.mark.parametrize("d", [2, 3, 4, 5, 6, 7])
def test_which_degrees_move_the_vertex_monotonically(d):
    """Odd d and d = 2: every weight w_i(s) is >= 0 and non-increasing in s (integer s and,
    odd d, the linear blend between), down to 0 at s = inf.  d = 4, 6: the paper's integer
    rules themselves raise w_2 from s = 0 to s = 1 (1/384 -> 81/6144 for d = 4), so no
    fractional rule can make the motion monotone there (docs/curves.md)."""
    from patching.curves.runs import vertex_limit_weights

    grid = [0, 1, 2, 3, 4, 6, 8] if d % 2 == 0 else [0, 0.25, 0.5, 1, 1.5, 2, 2.5, 3, 4, 6, 8]
    W = np.array([vertex_limit_weights(d, s) for s in grid] + [vertex_limit_weights(d, math.inf)])
    assert W.min() >= 0 and np.abs(W[-1]).max() == 0
    rises = np.diff(W, axis=0).max()
    if d in (4, 6):
        assert W[1, 1] > 1.5 * W[0, 1]  # w_2 grows: 1/384 -> 0.0132 (d = 4), 0.0157 -> 0.0266 (d = 6)
    else:
        assert rises <= 1e-15


@settings(max_examples=8, deadline=None)
@given(st.sampled_from([2, 3, 5, 7]), st.integers(0, 2**31))
def test_limit_at_the_vertex_moves_monotonically_with_sharpness(d, seed):
    """The distance of the vertex's limit point from P_v never increases with s when the
    symmetric differences S_i = d+_i + d-_i have pairwise non-negative inner products (a
    polygon bent to one side at v, e.g. locally convex); for d = 2, 3 there is one S_i, so
    always.  |sum_i w_i(s) S_i|^2 = sum_ij w_i w_j S_i.S_j is then a sum of non-increasing
    terms (the weights test above)."""
    rng = np.random.default_rng(seed)
    n = 3 * d + 6
    v = n // 2
    h = d // 2
    theta = rng.uniform(0, np.pi / 2, h)  # S_i in one quarter plane: S_i . S_j >= 0
    S = rng.uniform(0.1, 1.0, (h, 1)) * np.c_[np.cos(theta), np.sin(theta)]
    D = rng.normal(size=(h, 2))
    P = rng.normal(size=(n, 2)) * 3
    P[v] = 0.0
    for i in range(1, h + 1):
        P[v + i], P[v - i] = (S[i - 1] + D[i - 1]) / 2, (S[i - 1] - D[i - 1]) / 2
    grid = [0, 1, 2, 3, 4, math.inf] if d % 2 == 0 else [0, 0.25, 0.5, 0.75, 1, 1.5, 2, 2.5, 3, 4, math.inf]
    dist = np.array([np.linalg.norm(_vertex_limit(d, P, v, s) - P[v]) for s in grid])
    assert dist[-1] < 1e-13
    assert np.all(np.diff(dist) <= 1e-13)


def test_with_the_papers_integer_rules_the_vertex_can_move_away():
    """Demonstrations with exact numbers (docs/curves.md): d = 5 with S_2 = -26 S_1 puts the
    smooth limit point on P_v (13/60 - 26/120 = 0), and one sharp step moves it to
    P_v - (14/120) S_1; d = 4 on the convex polygon (-2, 1), (-1, 0), (0, 0), (1, 0), (2, 1)
    (S_1 = 0, S_2 = (0, 2)) moves it from 2/384 to 162/6144 away, five times farther."""
    P5 = np.zeros((21, 2))
    P5[:, 0] = np.arange(21) - 10.0
    P5[11], P5[9] = (1.0, 0.2), (-1.0, 0.2)  # S_1 = (0, 0.4) at v = 10
    P5[12], P5[8] = (2.0, -5.2), (-2.0, -5.2)  # S_2 = (0, -10.4) = -26 S_1
    c0, c1 = (_vertex_limit(5, P5, 10, s) for s in (0, 1))
    assert np.abs(c0 - P5[10]).max() < 1e-13
    assert np.allclose(c1 - P5[10], -14 / 120 * np.array([0.0, 0.4]), atol=1e-13)
    P4 = np.zeros((21, 2))
    P4[:, 0] = np.arange(21) - 10.0
    P4[:, 1] = np.maximum(np.abs(P4[:, 0]) - 1, 0)  # convex: flat over [-1, 1], then slope 1
    c0, c1 = (_vertex_limit(4, P4, 10, s) for s in (0, 1))
    assert np.allclose(c0, [0, 2 / 384], atol=1e-14)
    assert np.allclose(c1, [0, 162 / 6144], atol=1e-14)


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


def test_no_quartic_crease_rule_of_the_papers_structure_moves_the_vertex_monotonically():
    """[KSD]'s T_4 is one of three solutions of S M = M T with its structure (without the
    natural-configuration condition); d = 6 has one.  Each quartic solution moves the vertex's
    limit away from P_v on some polygon: the paper's and the second one raise w_2 at s = 1
    (a polygon with S_1 = 0), the degenerate one (negative weight) sends w_1 through zero, so
    |w_1| grows from s = 2 to s = 3 (a polygon with S_2 = 0).  So the non-monotone motion is
    not the choice of one solution among several (docs/curves.md)."""
    from patching.curves.creases import crease_scheme, crease_scheme_solutions
    from patching.curves.runs import vertex_limit_weights

    sols = crease_scheme_solutions(4)
    assert len(sols) == 3
    assert sum(np.abs(s.T - crease_scheme(4).T).max() < 1e-12 for s in sols) == 1
    for sc in sols:
        W = np.abs([vertex_limit_weights(4, k, sc) for k in range(6)])
        rises = np.diff(W, axis=0)  # |w_i| along s = 0..5 for the polygon with only S_i != 0
        assert rises.max() > 1e-4 * W.max(), sc.T


@pytest.mark.parametrize("d, flat, rise_until", [(4, 1, 1), (6, 2, 2)])
def test_even_degree_vertex_limit_on_a_convex_polygon_moves_away_then_back(d, flat, rise_until):
    """The measured behaviour of the paper's integer rules at even degree, as a distance from
    P_v to the curve (a point set, so no parameterisation enters): the polygon
    y = max(|x| - flat, 0) is convex and symmetric, S_i = 0 for i <= flat, S_(flat+1) = (0, 2).
    The closest point of the curve to P_v = (0, 0) is on the axis at y = 2 w_(flat+1)(s): it
    rises from s = 0 to s = rise_until (d = 4: 2/384 -> 162/6144, 81/16 times farther; d = 6:
    20 times), then falls monotonically to 0 at s = inf.  On this polygon the only path from
    the s = 0 point to the s = inf point is the axis, so no reading of "moves monotonically"
    (distance, or position along a path) holds."""
    from scipy.optimize import minimize_scalar

    from patching.curves.runs import vertex_limit_weights

    n = 21
    P = np.zeros((n, 2))
    P[:, 0] = np.arange(n) - 10.0
    P[:, 1] = np.maximum(np.abs(P[:, 0]) - flat, 0)
    ends = {0: math.inf, n - 1: math.inf}
    grid = [0, 1, 2, 3, 4, 6, math.inf]
    dist = []
    for s in grid:
        lim = Curve(P, d, corners={**ends, 10: s} if s else ends).limit()
        t = np.linspace(*lim.domain, 4001)
        r = np.linalg.norm(lim.evaluate(t), axis=1)
        k = int(np.argmin(r))
        best = minimize_scalar(lambda u: np.linalg.norm(lim.evaluate(u)), bounds=(t[k - 1], t[k + 1]),
                               method="bounded", options={"xatol": 1e-13})
        dist.append(best.fun)
        if s != math.inf:
            assert abs(best.fun - 2 * vertex_limit_weights(d, s)[flat]) < 1e-12
            assert abs(lim.evaluate(best.x)[0]) < 1e-6  # on the axis
    dist = np.array(dist)
    assert dist[-1] < 1e-13
    steps = np.diff(dist)
    assert (steps[:rise_until] > 0).all() and (steps[rise_until:] < 0).all()
    if d == 4:
        assert abs(dist[0] - 2 / 384) < 1e-13 and abs(dist[1] - 162 / 6144) < 1e-13
        assert abs(dist[1] / dist[0] - 81 / 16) < 1e-9
    else:
        assert dist[2] > 20 * dist[0]


@pytest.mark.parametrize("d, from_s", [(2, 0), (3, 0), (4, 1), (5, 0), (6, 2), (7, 0)])
def test_weights_are_non_increasing_from_the_second_or_third_sharp_step(d, from_s):
    """What does hold for every degree: each w_i(s) >= 0 is non-increasing for integer
    s >= from_s (0 for d = 2, 3, 5, 7; 1 for d = 4; 2 for d = 6) and tends to 0 like 2^-s, so
    from there on the vertex's limit approaches P_v monotonically on every polygon bent to one
    side (S_i . S_j >= 0), and on every polygon for d = 2, 3 (one weight)."""
    from patching.curves.runs import vertex_limit_weights

    W = np.array([vertex_limit_weights(d, s) for s in range(0, 14)])
    assert W.min() >= 0
    assert (np.diff(W[from_s:], axis=0) <= 1e-17).all()
    if from_s:
        assert (np.diff(W[: from_s + 1], axis=0) > 0).any()
    ratio = W[-1] / W[-2]
    assert np.allclose(ratio, 0.5, atol=2e-3)
