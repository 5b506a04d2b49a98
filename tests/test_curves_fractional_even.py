"""Fractional sharpness at even degree (``runs.fractional_even_limit``): the step where the
sharpness is fractional blends the smooth and the sharp limits on one knot structure (the
central span of length 2 - f, poles (1 - f) X + f c_1).  Checked: continuity in s at the
integers (both sides), an independent construction of the blend with scipy (least-squares
spline on the reduced knots), convex hull and C^(d-1), locality, closed polygons, and the
refusals (a polygon through the fractional step, a window too near an end); and a fractional
step before the curve's last level: the last-step blend of its window spliced into the sharp
branch, checked against the whole-polygon construction and the sharp branch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from patching.curves.curve import Curve
from patching.errors import UnsupportedError

EVEN = [2, 4, 6]


def _open(d, seed, n=24):
    return np.random.default_rng(seed).normal(size=(n, 2))


def _at(curve, t):
    return curve.limit().evaluate(t)


@pytest.mark.parametrize("d", EVEN)
@pytest.mark.parametrize("extra", [{}, {17: math.inf}, {18: 2.0}])
def test_continuous_in_s_at_the_integers(d, extra):
    """|c_s - c_k| <= C |s - k| at equal parameters (spans of the original polygon) for
    s -> 0+, 1-, 1+, 2-, with another infinitely sharp or integer-sharp vertex around; the
    domain length is linear in s between the integers (the central span 2 - f)."""
    n = 27
    P = _open(d, 11, n)
    ends = {0: math.inf, n - 1: math.inf}

    def curve(s):
        tags = {**ends, **extra}
        if s:
            tags[8] = s
        return Curve(P, d, corners=tags)

    for k, side in ((0, 1), (1, -1), (1, 1), (2, -1)):
        ref = curve(k).limit()
        errs = []
        for eps in (1e-4, 1e-7):
            c = curve(k + side * eps).limit()
            t = np.linspace(0, min(c.domain[1], ref.domain[1]), 3001)
            errs.append(np.abs(c.evaluate(t) - ref.evaluate(t)).max())
            assert abs(c.domain[1] - ref.domain[1]) <= eps  # the domain moves by (1 - f) / 2^L
        assert errs[1] < 1e-5 and errs[1] < 2e-3 * errs[0] + 1e-12, errs  # linear in eps
    lengths = [curve(s).limit().domain[1] for s in (1.25, 1.5, 1.75)]
    assert np.allclose(np.diff(lengths), np.diff(lengths)[0], atol=1e-12)


@pytest.mark.parametrize("d, f", [(4, 0.3), (6, 0.7), (2, 0.5)])
def test_blend_equals_an_independent_construction(d, f):
    """The blend built here with scipy alone: c_0 (s = 0) fitted by scipy's least-squares
    spline on the knots of the sharp step's limit c_1 (s = 1) with its central span widened to
    2 (exact: c_0 is polynomial there), then knots with the central span 2 - f and poles
    (1 - f) X + f c_1.  Equal to the exported limit to 1e-12."""
    from scipy.interpolate import make_lsq_spline

    n, v = 22, 10
    P = _open(d, 3, n)
    ends = {0: math.inf, n - 1: math.inf}
    c0 = Curve(P, d, corners=ends).limit()
    c1 = Curve(P, d, corners={**ends, v: 1}).limit()
    got = Curve(P, d, corners={**ends, v: f}).limit()
    from patching.curves.runs import CREASE, run_refined_size

    # c_1's knots in fine units (x 2).  Its crease point is point m - 1 of the refined
    # polygon (the last of the run 0..v), whose B-spline is centred at m - 1 - 1/2 (even d,
    # a sharp end at 0: pole j + d - J of the clamped run, knots k - d); its span [a, a + 1]
    k1 = c1.knots * 2
    m = run_refined_size(v + 1, d, CREASE, CREASE)
    a = m - 1 - 0.5 - 0.5
    kX = k1 + (k1 > a + 1e-9)  # central span widened to 2: c_0's fine knots without t0 = a + 1
    tt = np.linspace(0, kX[-1], 40 * len(kX))
    X = make_lsq_spline(tt, c0.evaluate(tt / 2), kX, d).c
    Ks = k1 + (1 - f) * (k1 > a + 1e-9)
    poles = (1 - f) * X + f * c1.poles
    assert np.abs(got.knots * 2 - Ks).max() < 1e-12
    assert np.abs(got.poles - poles).max() < 1e-12
    far = np.abs(np.arange(len(X)) - (m - 1 + d - (d - (d - 1) // 2))) > d + 1
    assert np.abs(X - c1.poles).max(axis=1)[far].max() < 1e-12  # local: the poles agree far from v


@pytest.mark.parametrize("d", EVEN)
@pytest.mark.parametrize("closed", [False, True])
def test_convex_hull_smoothness_and_locality(d, closed):
    """Poles are convex combinations of the polygon; interior knots simple except d-fold at
    the infinitely sharp vertex (C^(d-1) elsewhere); far from the fractional vertex the curve
    is the curve without the fractional tag (open polygons, where the parameters compare)."""
    from scipy.spatial import Delaunay

    n = 30
    P = np.random.default_rng(d).normal(size=(n, 2))
    tags = {8: 1.4, 20: math.inf} if not closed else {8: 1.4, 23: 1.6, 15: 2}
    c = Curve(P, d, closed, corners=tags)
    knots, W, _ = c.limit_operator()
    W = W.toarray()
    assert W.min() > -1e-13 and np.allclose(W.sum(axis=1), 1.0, atol=1e-13)
    lim = c.limit()
    values, counts = np.unique(lim.knots, return_counts=True)
    assert (counts[1:-1] == d).sum() == (0 if closed else 1) and counts[1:-1].max() <= d
    assert (counts[1:-1][counts[1:-1] < d] == 1).all()
    pts = lim.evaluate(np.linspace(*lim.domain, 4000))
    assert (Delaunay(P).find_simplex(pts, tol=1e-9) >= 0).all()
    if closed:
        return
    # far from vertex 8 the curve is the one without its tag: equal parameters on the left
    # (free end at 0), shifted by the lost length on the right of vertex 8
    ref = Curve(P, d, closed, corners={k: s for k, s in tags.items() if k != 8}).limit()
    shift = ref.domain[1] - lim.domain[1]
    assert 0 < shift < 1
    t = np.linspace(0, 8 - d / 2 - (d + 1) / 2 - 0.5, 200)
    assert np.abs(lim.evaluate(t) - ref.evaluate(t)).max() < 1e-12
    t = np.linspace(8 + (d + 1), lim.domain[1], 200)
    assert np.abs(lim.evaluate(t) - ref.evaluate(t + shift)).max() < 1e-12


def test_refusals():
    """An even-degree fractional sharpness below the curve's last level, and a polygon asked
    through the fractional step, are refused in one line; refine up to the step before works."""
    P = _open(4, 1, 24)
    c = Curve(P, 4, corners={5: 1.5, 15: 2})
    assert len(c.refine(1).points) > len(P)
    with pytest.raises(UnsupportedError, match="no polygon"):
        c.refine(2)
    c = Curve(P, 4, corners={5: 1.5, 15: 3})  # the fractional step comes before the last level
    assert len(c.refine(1).points) > len(P)
    with pytest.raises(UnsupportedError, match="step 2 blends"):
        c.refine(2)
    with pytest.raises(UnsupportedError, match="vertex 3"):  # its window reaches the free end
        Curve(P, 4, corners={3: 0.5, 15: 3}).limit()
    with pytest.raises(UnsupportedError, match="needs at least|too close|closer"):
        Curve(P, 4, corners={5: 0.5, 7: 0.5}).limit()


@pytest.mark.parametrize("d", [4, 6])
def test_closed_polygon_is_continuous_in_s(d):
    """Closed polygons clamp their periodic limit at a seam that the blend puts away from the
    tags, so the parameters start elsewhere than the integer curves'.  Aligned by the
    parameter of a(0) on b (a 1-D minimisation), the curve at s = eps is within O(eps) of the
    s = 0 curve and at s = 1 - eps of the s = 1 curve, at 2001 parameters."""
    from scipy.optimize import minimize_scalar

    n = 26
    P = np.random.default_rng(d + 40).normal(size=(n, 2))

    def aligned(a, b):
        T = b.domain[1]
        tb = np.linspace(0, T, 20001)
        p0 = a.evaluate(0.0)
        k = int(np.argmin(np.linalg.norm(b.evaluate(tb) - p0, axis=1)))
        r = minimize_scalar(lambda u: np.linalg.norm(b.evaluate(u % T) - p0), bounds=(tb[k] - T / 2e4, tb[k] + T / 2e4),
                            method="bounded", options={"xatol": 1e-13})
        t = np.linspace(0, a.domain[1], 2001)
        return np.abs(a.evaluate(t) - b.evaluate((t + r.x) % T)).max()

    smooth, sharp = Curve(P, d, True).limit(), Curve(P, d, True, corners={6: 1}).limit()
    for eps in (1e-4, 1e-7):
        assert aligned(Curve(P, d, True, corners={6: eps}).limit(), smooth) < 3 * eps
        assert aligned(Curve(P, d, True, corners={6: 1 - eps}).limit(), sharp) < 3 * eps
    assert aligned(Curve(P, d, True, corners={6: 0.5}).limit(), smooth) > 1e-3  # a different curve


@pytest.mark.parametrize("d, flat", [(4, 1), (6, 2)])
def test_between_integers_the_blend_adds_no_motion_of_its_own(d, flat):
    """On the convex polygons of the even-degree counterexample (test_curves_properties), the
    distance from P_v to the curve is monotone on each [k, k + 1] (measured at quarter
    steps): the fractional rule moves between the two integer curves without overshooting
    them; the non-monotone motion over s is the integer rules' (docs/curves.md)."""
    from scipy.optimize import minimize_scalar

    n = 21
    P = np.zeros((n, 2))
    P[:, 0] = np.arange(n) - 10.0
    P[:, 1] = np.maximum(np.abs(P[:, 0]) - flat, 0)
    ends = {0: math.inf, n - 1: math.inf}
    grid = np.linspace(0, 3, 13)
    dist = []
    for s in grid:
        lim = Curve(P, d, corners={**ends, 10: float(s)} if s else ends).limit()
        t = np.linspace(*lim.domain, 4001)
        k = int(np.argmin(np.linalg.norm(lim.evaluate(t), axis=1)))
        r = minimize_scalar(lambda u: np.linalg.norm(lim.evaluate(u)), bounds=(t[k - 1], t[k + 1]), method="bounded",
                            options={"xatol": 1e-13})
        dist.append(r.fun)
    steps = np.diff(np.array(dist)).reshape(3, 4)  # the quarter steps of [0, 1], [1, 2], [2, 3]
    assert all((row > 0).all() or (row < 0).all() for row in steps), steps


@pytest.mark.parametrize("d", EVEN)
def test_fractional_step_before_the_last_level_is_the_window_blend_spliced(d):
    """s_v = 1.5 (or 0.25) with another tag at s = 3: left of the midpoint the curve is the
    curve with v's tag alone (the whole-polygon last-step construction, an independent code
    path), right of it the sharp branch (s_v raised to ceil) shifted by (1 - f) / 2^ceil(s_v),
    the longer central span; between two early fractional vertices, the curve with the second
    one alone, shifted by the first's (1 - f) / 2^k.  Exact to 1e-13."""
    n = 64
    P = _open(d, 3, n)
    ends = {0: math.inf, n - 1: math.inf}
    c = Curve(P, d, corners={**ends, 14: 1.5, 30: 0.25, 48: 3.0}).limit()
    t = np.linspace(0, c.domain[1], 6001)
    left = Curve(P, d, corners={**ends, 14: 1.5}).limit()
    sharp = Curve(P, d, corners={**ends, 14: 2.0, 30: 1.0, 48: 3.0}).limit()
    middle = Curve(P, d, corners={**ends, 14: 2.0, 30: 0.25}).limit()
    a, m, b = t < 22, (t > 23) & (t < 37), t > 38
    assert np.abs(c.evaluate(t[a]) - left.evaluate(t[a])).max() < 1e-13
    assert np.abs(c.evaluate(t[m]) - middle.evaluate(t[m] - 0.5 / 4)).max() < 1e-13
    assert np.abs(c.evaluate(t[b]) - sharp.evaluate(t[b] - 0.5 / 4 - 0.75 / 2)).max() < 1e-13
    assert c.domain[1] == pytest.approx(sharp.domain[1] + 0.5 / 4 + 0.75 / 2, abs=1e-12)


def test_early_fractional_step_on_a_closed_polygon_is_continuous_in_s():
    P = np.random.default_rng(2).normal(size=(60, 2))
    ref = Curve(P, 4, True, corners={10: 2.0, 40: 3.0}).limit()
    errs = []
    for eps in (1e-4, 1e-7):
        c = Curve(P, 4, True, corners={10: 2.0 - eps, 40: 3.0}).limit()
        t = np.linspace(0, min(c.domain[1], ref.domain[1]), 3001)
        errs.append(np.abs(c.evaluate(t) - ref.evaluate(t)).max())
    assert errs[1] < 1e-5 and errs[1] < 2e-3 * errs[0] + 1e-12, errs


def test_overlapping_early_windows_are_refused():
    P = _open(4, 5, 40)
    with pytest.raises(UnsupportedError, match="overlap|too close|closer|needs at least"):
        Curve(P, 4, corners={0: math.inf, 39: math.inf, 14: 1.5, 17: 1.5, 30: 3.0}).limit()
