"""Span extraction against the classic uniform matrix and a direct Cox-de Boor evaluation."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from math import comb

from tests.reference_bspline import cubic_span_extraction


def cox_de_boor(knots, i, p, t):
    """N_{i,p}(t) by the recursion, right-continuous (The NURBS Book, eq. 2.5)."""
    if p == 0:
        return 1.0 if knots[i] <= t < knots[i + 1] else 0.0
    out = 0.0
    if knots[i + p] > knots[i]:
        out += (t - knots[i]) / (knots[i + p] - knots[i]) * cox_de_boor(knots, i, p - 1, t)
    if knots[i + p + 1] > knots[i + 1]:
        out += (knots[i + p + 1] - t) / (knots[i + p + 1] - knots[i + 1]) * cox_de_boor(knots, i + 1, p - 1, t)
    return out


def test_uniform_is_the_classic_bspline_to_bezier_matrix():
    expected = np.array([[1, 4, 1, 0], [0, 4, 2, 0], [0, 2, 4, 0], [0, 1, 4, 1]]) / 6
    np.testing.assert_allclose(cubic_span_extraction(np.ones((1, 5)))[0], expected, atol=1e-15)


def test_clamped_start_interpolates_the_first_points():
    w = cubic_span_extraction(np.array([[0.0, 0.0, 1.0, 2.0, 3.0]]))[0]
    np.testing.assert_allclose(w[0], [1, 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(w[1], [0, 1, 0, 0], atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.one_of(st.just(0.0), st.floats(1e-3, 20.0)), min_size=5, max_size=5).filter(lambda e: e[2] > 0),
    st.floats(0.0, 1.0),
)
def test_bezier_form_equals_the_bspline_span(e, s):
    """Evaluate the Bézier form at s and the B-spline by Cox-de Boor at t3 + s e2."""
    e = np.array(e)
    w = cubic_span_extraction(e[None])[0]
    knots = np.concatenate([[0.0], np.cumsum(np.concatenate([[0.0], e]))])  # t_0 (unused) .. t_6
    knots = np.concatenate([[knots[1] - 1.0], knots[1:], [knots[-1] + 1.0]])  # t_0..t_7
    t = knots[3] + s * e[2]
    t = min(t, knots[4] - 1e-12 * max(1.0, e[2]))  # stay inside the half-open span
    bern = np.array([comb(3, i) * s**i * (1 - s) ** (3 - i) for i in range(4)])
    basis_bezier = bern @ w
    basis_direct = np.array([cox_de_boor(knots, j, 3, t) for j in range(4)])
    # Tolerance: t was nudged by 1e-12 of the span to stay in the half-open interval.
    np.testing.assert_allclose(basis_bezier, basis_direct, atol=1e-9)
    assert abs(w.sum(axis=1) - 1).max() < 1e-14
