"""Control vectors ([KSD] sec. 4): the crease functions solved from S M = M T against
[KSD] Table 1, and the exactness of their refinement and limit."""

from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np
import pytest
from scipy.interpolate import BSpline

from patching.curves.control_vectors import crease_function
from patching.curves.curve import Curve

# [KSD] Table 1: the masks of N^_d on the refined uniform B-splines, times 2^d
TABLE_1 = {
    2: [2, 2],
    3: [6],
    4: [F(12, 7), F(60, 7), F(60, 7), F(12, 7)],
    5: [F(30, 7), F(180, 7), F(30, 7)],
    6: [F(360, 239), F(2520, 239), F(8640, 239), F(8640, 239), F(2520, 239), F(360, 239)],
    7: [F(840, 239), F(6720, 239), F(25200, 239), F(6720, 239), F(840, 239)],
}


@pytest.mark.parametrize("d", sorted(TABLE_1))
def test_crease_function_masks_are_table_1(d):
    cf = crease_function(d)
    assert cf.residual < 1e-13
    assert np.allclose(cf.mask * 2**d, [float(x) for x in TABLE_1[d]], atol=1e-12)
    # support width 2 floor(d/2) spans, value 1 at the crease ([KSD] sec. 4)
    assert len(cf.coefficients) == 2 * (d // 2) - 1
    assert cf.coefficients[(len(cf.coefficients) - 1) // 2] == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("d", range(2, 8))
def test_crease_function_is_refinable_and_C0(d):
    """N^_d(t) = 1/2 N^_d(2t) + sum_i c_i B_d(2t - i): evaluate both sides independently."""
    cf = crease_function(d)
    w = d // 2
    # N^_d on the knots (-w..-1, 0 x d, 1..w) (unit spans; its 2w - 1 B-splines), padded
    # with d + 1 zero coefficients on each side for scipy
    core = np.r_[np.arange(-w, 0.0), np.zeros(d), np.arange(1.0, w + 1)]
    assert len(core) - d - 1 == len(cf.coefficients)
    knots = np.r_[np.arange(-w - d - 1, -w, 1.0), core, np.arange(w + 1, w + d + 2, 1.0)]
    N = BSpline(knots, np.r_[np.zeros(d + 1), cf.coefficients, np.zeros(d + 1)], d, extrapolate=False)
    t = np.linspace(-w + 1e-9, w - 1e-9, 501)
    fine = np.nan_to_num(N(2 * t))
    # the fine uniform B-splines inside the support, unit spacing halved
    count = len(cf.mask)
    first = -w + 0.0  # fine knots in units of the fine spacing 1/2: support starts at -2w
    rhs = 0.5 * fine
    for k, c in enumerate(cf.mask):
        a = (-2 * w + k) / 2.0
        b = BSpline.basis_element(a + np.arange(d + 2) / 2.0, extrapolate=False)
        rhs = rhs + c * np.nan_to_num(b(t))
    assert np.abs(np.nan_to_num(N(t)) - rhs).max() < 1e-12
    assert count == 4 * w - d and first == -w
    # C0 at 0: the one-sided derivatives differ
    dN = N.derivative()
    assert abs(dN(-1e-9) - dN(1e-9)) > 0.1


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("d", range(2, 8))
@pytest.mark.parametrize("s", [math.inf, 2.0, 0.5])
def test_refinement_keeps_the_exact_limit(d, closed, s):
    rng = np.random.default_rng(d)
    n = 4 * d + 4
    P = rng.normal(size=(n, 3))
    c = Curve(P, d, closed, vectors={n // 2: (rng.normal(size=3), s), n // 4: (rng.normal(size=3), math.inf)})
    lim = c.limit()
    t = np.linspace(*lim.domain, 301)
    for k in (1, 3):
        fine = c.refine(k)
        assert np.abs(fine.evaluate(t * 2**k) - lim.evaluate(t)).max() < 1e-12
    # the vector changes the curve (it is not dropped on the way)
    plain = Curve(P, d, closed).limit()
    assert np.abs(lim.evaluate(t) - plain.evaluate(t)).max() > 1e-3


def test_odd_vector_at_control_point_minus_limit_point_recovers_a_sharp_corner():
    """[KSD] sec. 4: with V = P_v - (limit point of the smooth curve at v) the cubic control
    vector reproduces the Pixar sharp corner, so the curve passes through P_v."""
    rng = np.random.default_rng(3)
    n = 12
    P = rng.normal(size=(n, 2))
    v = 6
    smooth = Curve(P, 3, True)
    limit_v = (P[v - 1] + 4 * P[v] + P[v + 1]) / 6
    assert np.allclose(smooth.evaluate(float(v)), limit_v, atol=1e-14)
    c = Curve(P, 3, True, vectors={v: (P[v] - limit_v, math.inf)})
    assert np.allclose(c.evaluate(float(v)), P[v], atol=1e-13)
