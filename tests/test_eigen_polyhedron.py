"""Tests for patching/eigen_polyhedron.py: the local [LFS16] rules around one vertex.

References written independently here: the classic Catmull-Clark masks, and a cubic
B-spline knot insertion (Boehm, The NURBS Book A5.1) taken as a tensor product.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from patching.rules import eigen_polyhedron as ep

OPTIONS = [
    ("standard", "appendix"),
    ("standard", "fourier"),
    ("modified", "appendix"),
    ("modified", "fourier"),
]


def random_intervals(rng, n, ratio):
    """n intervals in [1, ratio], with 1 and ratio both present when n >= 2."""
    d = rng.uniform(1.0, ratio, size=n)
    if ratio > 1.0:
        k = rng.permutation(n)[:2]
        d[k[0]], d[k[1]] = 1.0, ratio
    return d


# ---------------------------------------------------------------------------------------------
# Independent references


def catmull_clark_matrix(n):
    """Classic Catmull-Clark on [V, E_0.., F_0..], from the textbook masks."""
    size = 2 * n + 1
    E = lambda i: 1 + i % n  # noqa: E731
    F = lambda i: 1 + n + i % n  # noqa: E731
    m = np.zeros((size, size))
    face = np.zeros((n, size))
    for i in range(n):  # face point: average of the 4 corners
        for k in (0, E(i), E(i + 1), F(i)):
            face[i, k] += 0.25
        m[F(i)] = face[i]
    for i in range(n):  # edge point: (V + E_i + two new face points) / 4
        m[E(i), 0] += 0.25
        m[E(i), E(i)] += 0.25
        m[E(i)] += 0.25 * (face[i - 1] + face[i])
    # vertex: (n-2)/n V + sum(E_i)/n^2 + sum(new face points)/n^2 (Catmull-Clark 1978; the
    # same as [TLC] sec. 2: 1 - 7/(4n), 3/(2n^2) on E_i, 1/(4n^2) on F_i)
    m[0, 0] = (n - 2.0) / n
    for i in range(n):
        m[0, E(i)] += 1.0 / n**2
        m[0] += face[i] / n**2
    return m


def boehm_insert(knots, t):
    """Insert knot t into a cubic B-spline: returns (new knots, matrix A with Q = A @ P).

    Control point k is the blossom of knots[k+1], knots[k+2], knots[k+3] (no clamping); The
    NURBS Book A5.1 with p = 3."""
    knots = np.asarray(knots, dtype=float)
    m = knots.size - 4
    j = int(np.searchsorted(knots, t, side="right")) - 1  # knots[j] <= t < knots[j+1]
    a = np.zeros((m + 1, m))
    for k in range(m + 1):
        if k <= j - 3:
            a[k, k] = 1.0
        elif k <= j:
            w = (t - knots[k]) / (knots[k + 3] - knots[k])
            a[k, k - 1] = 1.0 - w
            a[k, k] = w
        else:
            a[k, k - 1] = 1.0
    return np.insert(knots, j + 1, t), a


def curve_refinement_rows(d_left, d_right, pad=(0.7, 1.3), outer=None):
    """1-D midpoint refinement at a vertex knot with intervals d_left | d_right on each side.

    Intervals along the line: pad, outer_l, d_left, d_right, outer_r, pad with outer = (d_left,
    d_right) by default (the edge beyond each neighbour carries the spoke's interval, as the
    eigen rules assume).  Returns a (3, 3)
    matrix: rows = new [left edge point, vertex point, right edge point], columns = old
    [left neighbour, vertex, right neighbour]; asserts that nothing else contributes."""
    outer = (d_left, d_right) if outer is None else outer
    intervals = [pad[0], pad[0], outer[0], d_left, d_right, outer[1], pad[1], pad[1]]
    knots = np.concatenate([[0.0], np.cumsum(intervals)])
    t2 = knots[4]  # the vertex knot: vertex point = f(t1, t2, t3) = control point 2
    total = np.eye(knots.size - 4)
    for t in (t2 - d_left / 2.0, t2 + d_right / 2.0):
        knots, a = boehm_insert(knots, t)
        total = a @ total

    def index(triple):
        for k in range(knots.size - 3):
            if np.allclose(knots[k + 1 : k + 4], triple):
                return k
        raise AssertionError(triple)

    mb, mc = t2 - d_left / 2.0, t2 + d_right / 2.0
    rows = [index((t2 - d_left, mb, t2)), index((mb, t2, mc)), index((t2, mc, t2 + d_right))]
    sub = total[rows]
    assert np.abs(np.delete(sub, [1, 2, 3], axis=1)).max() < 1e-14  # locality
    return sub[:, [1, 2, 3]]


def nurbs_valence4_matrix(d, outer=None):
    """Valence-4 vertex: tensor product of 1-D refinements; u along spokes 0/2, v along 1/3.

    outer: intervals a_0..a_3 of the edges continuing the spokes beyond E_i (default d)."""
    a = d if outer is None else outer
    wu = curve_refinement_rows(d[2], d[0], outer=(a[2], a[0]))  # index 0: -u, 1: centre, 2: +u
    wv = curve_refinement_rows(d[3], d[1], outer=(a[3], a[1]))
    # local point -> (u slot, v slot)
    slots = {0: (1, 1), 1: (2, 1), 2: (1, 2), 3: (0, 1), 4: (1, 0)}
    slots.update({5: (2, 2), 6: (0, 2), 7: (0, 0), 8: (2, 0)})
    m = np.zeros((9, 9))
    for new, (pu, pv) in slots.items():
        for old, (qu, qv) in slots.items():
            m[new, old] = wu[pu, qu] * wv[pv, qv]
    return m


# ---------------------------------------------------------------------------------------------
# Reductions: Catmull-Clark and NURBS


@pytest.mark.parametrize("angles,lengths", OPTIONS)
@pytest.mark.parametrize("n", range(3, 13))
def test_uniform_intervals_give_catmull_clark(n, angles, lengths):
    m = ep.local_subdivision_matrix([2.5] * n, angles=angles, lengths=lengths)
    # 1e-14: the bilinear solves return 1/2 up to a few ulps.
    np.testing.assert_allclose(m, catmull_clark_matrix(n), rtol=0, atol=1e-14)


def test_boehm_reference_is_uniform_cubic_on_uniform_knots():
    # the reference itself: uniform cubic midpoint masks (1/2, 1/2) and (1/8, 6/8, 1/8)
    np.testing.assert_allclose(
        curve_refinement_rows(1.0, 1.0),
        [[0.5, 0.5, 0.0], [0.125, 0.75, 0.125], [0.0, 0.5, 0.5]],
        atol=1e-15,
    )


@pytest.mark.parametrize("angles,lengths", OPTIONS)
@pytest.mark.parametrize("seed", range(8))
def test_valence4_is_nurbs_knot_insertion(seed, angles, lengths):
    d = random_intervals(np.random.default_rng(seed), 4, 20.0)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    # 1e-13: rational weights of intervals up to 20, each through a quadratic solve.
    np.testing.assert_allclose(m, nurbs_valence4_matrix(d), rtol=0, atol=1e-13)


def test_valence4_needs_outer_intervals_equal_to_spokes():
    # The local rule reads the spoke intervals only: it is knot insertion exactly when the
    # edges continuing the spokes ([FSLYJ]'s a_i) carry the spoke intervals, as after one
    # refinement step.  With other a_i the NURBS refinement differs, so the rule is not it.
    d = np.array([1.0, 3.0, 2.0, 5.0])
    m = ep.local_subdivision_matrix(d)
    np.testing.assert_allclose(m, nurbs_valence4_matrix(d), atol=1e-14)
    assert np.abs(m - nurbs_valence4_matrix(d, outer=[2.0, 1.0, 4.0, 3.0])).max() > 1e-2


def test_valence4_eigenvalues_are_the_bicubic_ones():
    ev = ep.subdivision_eigenvalues([1.0, 3.0, 7.0, 2.0])
    bicubic = [1, 0.5, 0.5, 0.25, 0.25, 0.25, 0.125, 0.125, 0.0625]  # products of 1, 1/2, 1/4, 1/8
    np.testing.assert_allclose(ev, bicubic, atol=1e-13)


# ---------------------------------------------------------------------------------------------
# The eigen-polyhedron property and the reconstructions


@pytest.mark.parametrize("angles,lengths", OPTIONS)
@pytest.mark.parametrize("n", [3, 5, 6, 7, 9])
def test_eigen_polyhedron_is_scaled_and_translated(n, angles, lengths):
    d = random_intervals(np.random.default_rng(n), n, 5.0)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    p0 = ep.eigen_polyhedron(d, angles=angles, lengths=lengths)
    c = ep.rule_coefficients(d, angles=angles, lengths=lengths)
    expected = c.lam * p0 + c.translation[None, :]
    np.testing.assert_allclose(m @ p0, expected, rtol=0, atol=1e-13)


def test_appendix_lengths_reductions():
    np.testing.assert_allclose(ep.spoke_lengths([3.0] * 7, "appendix"), [3.0] * 7, rtol=1e-15)
    d = np.array([1.0, 4.0, 2.0, 9.0])
    np.testing.assert_allclose(
        ep.spoke_lengths(d, "appendix"), (2 * d + np.roll(d, -2)) / 3, rtol=1e-15
    )
    np.testing.assert_allclose(
        ep.spoke_lengths(d, "fourier"), (2 * d + np.roll(d, -2)) / 3, rtol=1e-14
    )
    u = ep.spoke_lengths([2.0] * 9, "fourier")
    np.testing.assert_allclose(u, u[0], rtol=1e-14)


@pytest.mark.parametrize("n", [3, 5, 6, 8, 11])
def test_modified_angles_properties(n):
    rng = np.random.default_rng(100 + n)
    for ratio in (1.0, 5.0, 1e3, 1e6):
        d = random_intervals(rng, n, ratio)
        th = ep.eigen_angles(d, "modified")
        assert abs(th.sum() - 2 * math.pi) < 1e-13
        assert np.all(th > 0) and np.all(th < math.pi)
    np.testing.assert_allclose(ep.eigen_angles([1.7] * n, "modified"), 2 * math.pi / n, rtol=1e-14)


def test_modified_angles_valence4_and_small_interval():
    th = ep.eigen_angles([1, 5, 2, 30.0], "modified")
    np.testing.assert_allclose(th, math.pi / 2, rtol=1e-14)
    # [ZTL]: a spoke whose interval is tiny compared with the others makes both sectors
    # beside it tend to right angles (the zero-interval = double-knot limit of Fig. 4).
    th = ep.eigen_angles([1e-9, 1, 1, 1, 1], "modified")
    assert abs(th[0] - math.pi / 2) < 1e-6 and abs(th[-1] - math.pi / 2) < 1e-6


def _seed001_angles(d):
    """[ZTL]'s angle rule transcribed literally (eq. 10 and the case analysis after it, the
    second "(2) n != 3" read as n = 3), loop by loop; returns (angles, branch)."""
    n = len(d)
    p = [d[i] * d[(i + 1) % n] for i in range(n)]
    pre = []
    for i in range(n):
        k = n * p[i] / sum(p)
        if k < 1:
            pre.append(math.pi / 2 - (2 - 8 / n) * math.atan(k))
        else:
            pre.append((4 / n - 0.5) * math.pi + (2 - 8 / n) * math.atan((1 + k) / 2))
    total, tmax = sum(pre), max(pre)
    is_max = [abs(t - tmax) <= 1e-12 * tmax for t in pre]
    n_max = sum(is_max)
    if n == 3:
        return [2 * math.pi / total * t for t in pre], "n = 3"
    if tmax * n_max < 2 * math.pi:
        scale = (2 * math.pi - tmax * n_max) / (total - tmax * n_max)
        return [t if m else scale * t for t, m in zip(pre, is_max)], "keep maxima"
    if n_max == n:
        return [2 * math.pi / total * t for t in pre], "all maximal"
    half = max(n_max, n - n_max)
    return [
        2 * math.pi * half / (n * tmax * n_max) * t if m else 2 * math.pi * (n - half) / (n * (total - tmax * n_max)) * t
        for t, m in zip(pre, is_max)
    ], "split"


def test_modified_angles_follow_seed001_text_in_every_branch():
    """eigen_angles("modified") against the literal transcription, on [ZTL]'s figure
    configurations, random ones, and constructed ones reaching each branch (Fig. 5's 1, 10,
    10, 10, 10 keeps its two sectors beside the short spoke at 86.4 degrees)."""
    cases = [[1, 15, 1, 1, 15], [1, 10, 10, 10, 10], [1, 10, 10], [1, 1, 1e4, 1e4, 1e4],
             [100, 100, 1, 1, 100, 100, 100], [100, 100, 1, 1, 100, 100, 1, 1], [1, 1, 1, 5, 5],
             [5000, 1, 1, 5000, 5000, 5000, 5000], [1, 1e-4, 1, 1e-4, 1, 1e-4, 1, 1e-4, 1, 1e-4, 1, 1]]
    rng = np.random.default_rng(1)
    cases += [list(rng.uniform(1e-6, 1, n)) for n in (3, 5, 6, 7, 8) for _ in range(20)]
    cases += [list(10.0 ** rng.uniform(-4, 0, n)) for n in (5, 6, 8, 12) for _ in range(20)]
    branches = set()
    for d in cases:
        expected, branch = _seed001_angles(d)
        branches.add(branch)
        np.testing.assert_allclose(ep.eigen_angles(d, "modified"), expected, rtol=1e-13)
    assert branches == {"n = 3", "keep maxima", "split"}, branches  # "all maximal" = uniform
    th = ep.eigen_angles([1, 10, 10, 10, 10], "modified")
    assert math.degrees(th[0]) == pytest.approx(86.44, abs=0.01) and th[0] == pytest.approx(th[4], rel=1e-15)


def test_vertex_rule_uniform_and_affine():
    for n in range(3, 10):
        w = ep.vertex_rule_weights([1.0] * n)
        np.testing.assert_allclose(w, catmull_clark_matrix(n)[0], atol=1e-15)
    w = ep.vertex_rule_weights([1, 3, 2, 8, 5.0])
    assert abs(w.sum() - 1) < 1e-15 and np.all(w > 0)


def _real_roots(p00, p10, p01, p11, x):
    roots, ok = ep.bilinear_roots(p00, p10, p01, p11, x)
    return [tuple(r) for r in roots[0][ok[0]]]


def test_bilinear_roots_closed_form_against_forward_map():
    rng = np.random.default_rng(7)
    for _ in range(200):
        p = rng.normal(size=(4, 2))
        s, t = rng.uniform(0, 1, size=2)
        x = (1 - s) * (1 - t) * p[0] + s * (1 - t) * p[1] + (1 - s) * t * p[2] + s * t * p[3]
        roots = _real_roots(p[0], p[1], p[2], p[3], x)
        assert min(math.hypot(a - s, b - t) for a, b in roots) < 1e-9
    # parallelogram: linear case, one root
    roots = _real_roots([0, 0], [1, 0], [0, 1], [1, 1], [0.3, 0.6])
    assert len(roots) == 1 and np.allclose(roots[0], (0.3, 0.6), atol=1e-15)


def _convex_quads(rng, k):
    """k random convex quads (p00, p10, p01, p11): a unit square's corners moved by < 0.3."""
    base = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    return base[None] + rng.uniform(-0.3, 0.3, size=(k, 4, 2))


def test_bilinear_inverse_solves_many_problems_at_once():
    """One call for 10,000 quads recovers every (s, t) in the unit square (the forward map is
    the reference), and equals the solution of each problem solved alone."""
    rng = np.random.default_rng(11)
    k = 10_000
    p = _convex_quads(rng, k) * rng.uniform(0.1, 10, size=(k, 1, 1))
    st = rng.uniform(0, 1, size=(k, 2))
    s, t = st[:, :1], st[:, 1:]
    x = (1 - s) * (1 - t) * p[:, 0] + s * (1 - t) * p[:, 1] + (1 - s) * t * p[:, 2] + s * t * p[:, 3]
    got = ep.bilinear_inverse(p[:, 0], p[:, 1], p[:, 2], p[:, 3], x)
    assert got.shape == (k, 2)
    # a 2x2 solve polished by Newton: round-off of O(1) coordinates, amplified by the Jacobian
    assert np.abs(got - st).max() < 1e-12
    for j in rng.choice(k, 20, replace=False):
        alone = ep.bilinear_inverse(p[j, 0], p[j, 1], p[j, 2], p[j, 3], x[j])
        assert np.array_equal(alone[0], got[j])


def test_bilinear_inverse_names_the_failing_problem():
    rng = np.random.default_rng(12)
    p = _convex_quads(rng, 5)
    x = p.mean(axis=1)
    x[3] = [50.0, -40.0]  # far outside quad 3: no real root, or none near the square
    labels = np.array([10, 11, 12, 13, 14])
    try:
        st = ep.bilinear_inverse(p[:, 0], p[:, 1], p[:, 2], p[:, 3], x, "face", labels)
    except ep.BilinearError as exc:
        assert exc.index == (3,) and "face 13" in str(exc)
    else:  # a real root far away: taken as the nearest branch, and it solves the equation
        s, t = st[3]
        fwd = (1 - s) * (1 - t) * p[3, 0] + s * (1 - t) * p[3, 1] + (1 - s) * t * p[3, 2] + s * t * p[3, 3]
        assert np.allclose(fwd, x[3])
    # a quad folded over itself: x has two preimages in the square, (0.8, 0.5) and (0.5, 0.8)
    q = np.array([[-1, -1], [0, 0], [0, 0], [0, 2]], float)
    with pytest.raises(ep.BilinearError, match="folds over"):
        ep.bilinear_inverse(q[0], q[1], q[2], q[3], [-0.1, 0.7])


# ---------------------------------------------------------------------------------------------
# Eigenvalues: 1 > lambda = lambda > |others|


def eigen_gap(d, angles="standard", lengths="fourier"):
    """(ok, |mu| / lambda) with mu the largest eigenvalue after 1, lambda, lambda."""
    ev = ep.subdivision_eigenvalues(d, angles=angles, lengths=lengths)
    lam = ep.characteristic_scale(len(d)).lam
    mods = np.abs(ev)
    # 1e-9: eigenvalues of a non-symmetric matrix at a double eigenvalue are only accurate to
    # about sqrt(eps) when it is defective; here it is semisimple and far better, but keep slack.
    ok = abs(ev[0] - 1) < 1e-9 and abs(ev[1] - lam) < 1e-9 and abs(ev[2] - lam) < 1e-9
    return ok and mods[3] < lam - 1e-9, mods[3] / lam


@pytest.mark.parametrize("ratio", [1.0, 2.0, 5.0])
@pytest.mark.parametrize("n", range(3, 17))
def test_subdominant_double_eigenvalue_moderate_ratios(n, ratio):
    rng = np.random.default_rng(1000 * n + int(ratio))
    for _ in range(6):
        d = random_intervals(rng, n, ratio)
        ok, gap = eigen_gap(d)
        assert ok, (n, d.tolist(), gap)


@pytest.mark.parametrize("n", range(3, 17))
def test_subdominant_double_eigenvalue_ratio_20(n):
    rng = np.random.default_rng(7 * n)
    for _ in range(6):
        d = random_intervals(rng, n, 20.0)
        ok, gap = eigen_gap(d)
        assert ok, (n, d.tolist(), gap)


@pytest.mark.parametrize("angles", ["standard", "modified"])
@pytest.mark.parametrize("n", [3, 6, 10])
def test_subdominant_double_eigenvalue_ratio_1e4_robust_valences(n, angles):
    # Valences 3, 6, 10 kept the eigen-structure in every sample up to ratio 1e4 (benchmark).
    rng = np.random.default_rng(13 * n)
    for _ in range(5):
        d = random_intervals(rng, n, 1e4)
        ok, gap = eigen_gap(d, angles=angles)
        assert ok, (n, d.tolist(), gap)


@pytest.mark.parametrize("angles", ["standard", "modified"])
def test_extreme_ratio_loses_the_eigen_structure(angles):
    # Finding: beyond ratio ~100 some valence-5, 8 and 12 configurations get a negative
    # eigenvalue of modulus > lambda (with either angle choice), so the vertex is not G1.  This is
    # one of them (ratio 1e4); the same happens inside [ZTL]'s test range [1e-6, 1].
    for d in (
        [10000.0, 107.5090358880951, 3152.15105974721, 258.1861017480902, 1.0],
        [0.67209927957375, 0.0034093992543232, 0.0011118918743652, 0.76647357270208,
         0.00016671997205609],
    ):
        ev = ep.subdivision_eigenvalues(d, angles=angles)
        lam = ep.characteristic_scale(5).lam
        assert ev[1].real < -lam and abs(ev[1].imag) < 1e-12
        np.testing.assert_allclose(ev[2:4], lam, atol=1e-12)  # the designed pair is still there


@pytest.mark.parametrize("n", range(3, 17))
def test_appendix_lengths_double_eigenvalue_up_to_ratio_5(n):
    rng = np.random.default_rng(17 * n)
    for _ in range(6):
        d = random_intervals(rng, n, 5.0)
        ok, gap = eigen_gap(d, lengths="appendix")
        assert ok, (n, d.tolist(), gap)


def test_appendix_lengths_lose_the_eigen_structure_at_ratio_10():
    # Finding (see spoke_lengths): with the reconstructed [FSLYJ] appendix lengths this valence-7
    # vertex gets an eigenvalue of modulus > 1 (the scheme diverges); the [LFS16] lengths of
    # [TLC] give 1 > lambda = lambda > |others| for the same intervals.
    d = [2.0, 10.0, 1.0, 10.0, 1.0, 5.0, 5.0]
    ok, _ = eigen_gap(d, lengths="appendix")
    assert not ok
    assert np.abs(ep.subdivision_eigenvalues(d, lengths="appendix")).max() > 1.0
    ok, gap = eigen_gap(d, lengths="fourier")
    assert ok and gap < 0.8


@pytest.mark.parametrize("n", range(3, 17))
def test_coefficients_in_unit_range_up_to_ratio_5(n):
    # default rules: every face/edge coefficient in [0, 1] (a convex combination) for ratio <= 5
    rng = np.random.default_rng(19 * n)
    for _ in range(6):
        d = random_intervals(rng, n, 5.0)
        c = ep.rule_coefficients(d)
        coef = np.concatenate([c.alpha.ravel(), c.beta.ravel()])
        assert np.all((coef >= 0) & (coef <= 1)), (n, d.tolist())
        assert np.all(ep.local_subdivision_matrix(d) >= 0)


@pytest.mark.parametrize("n", [3, 5, 6, 8, 12])
def test_face_solve_has_exactly_one_root_in_the_square(n):
    # uniqueness of eq. (12)'s solution: the other root of the quadratic (if real) lies outside
    rng = np.random.default_rng(23 * n)
    for ratio in (1.0, 5.0, 20.0):
        d = random_intervals(rng, n, ratio)
        p0 = ep.eigen_polyhedron(d)
        c = ep.rule_coefficients(d)
        for i in range(n):
            e0, e1 = p0[ep.edge_index(n, i)], p0[ep.edge_index(n, i + 1)]
            f = p0[ep.face_index(n, i)]
            roots = _real_roots(p0[0], e0, e1, f, c.translation + c.lam * f)
            inside = [r for r in roots if -1e-12 <= min(r) and max(r) <= 1 + 1e-12]
            assert len(inside) == 1
            np.testing.assert_allclose(inside[0], c.alpha[i], atol=1e-12)


def test_coefficients_leave_unit_range_for_valence3_at_ratio_100():
    # Finding: valence 3, ratio 100: edge coefficients leave [0, 1] (the target point of the
    # eigen-polyhedron leaves the edge quad), the rule has negative weights; the eigen-structure
    # still holds.
    d = [1.0, 1.0, 100.0]
    c = ep.rule_coefficients(d)
    assert c.beta.min() < -0.05 and c.beta.max() > 1.05
    assert ep.local_subdivision_matrix(d).min() < 0
    assert eigen_gap(d)[0]


@pytest.mark.parametrize("n", range(3, 17))
def test_modified_angles_double_eigenvalue_ratio_20(n):
    rng = np.random.default_rng(11 * n)
    for _ in range(6):
        d = random_intervals(rng, n, 20.0)
        ok, gap = eigen_gap(d, angles="modified")
        assert ok, (n, d.tolist(), gap)


# ---------------------------------------------------------------------------------------------
# Limit point and tangent plane


@pytest.mark.parametrize("angles,lengths", OPTIONS)
@pytest.mark.parametrize("n", [3, 5, 6, 8])
def test_limit_point_equals_repeated_subdivision(n, angles, lengths):
    rng = np.random.default_rng(n)
    d = random_intervals(rng, n, 5.0)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    w = ep.limit_point_weights(d, angles=angles, lengths=lengths)
    assert abs(w.sum() - 1) < 1e-14
    np.testing.assert_allclose(w @ m, w, atol=1e-14)  # left eigenvector of 1
    p = rng.normal(size=(2 * n + 1, 3))
    q = np.linalg.matrix_power(m, 150) @ p  # lambda^150 < 1e-20 for every valence tested
    # 1e-10 (as asked): all points of the ring converge to the limit point
    assert np.abs(q - w @ p).max() < 1e-10


@pytest.mark.parametrize("angles,lengths", OPTIONS)
@pytest.mark.parametrize("n", [3, 5, 7])
def test_tangent_plane_equals_repeated_subdivision(n, angles, lengths):
    rng = np.random.default_rng(20 + n)
    d = random_intervals(rng, n, 3.0)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    tw = ep.tangent_weights(d, angles=angles, lengths=lengths)
    p0 = ep.eigen_polyhedron(d, angles=angles, lengths=lengths)
    lam = ep.characteristic_scale(n).lam
    np.testing.assert_allclose(tw.sum(axis=1), 0, atol=1e-13)
    np.testing.assert_allclose(tw @ m, lam * tw, atol=1e-13)
    np.testing.assert_allclose(tw @ p0, np.eye(2), atol=1e-13)
    p = rng.normal(size=(2 * n + 1, 3))
    normal = np.cross(tw[0] @ p, tw[1] @ p)
    normal /= np.linalg.norm(normal)
    # Subdivide, removing the limit point's share each step and rescaling by 1/lambda (so that
    # round-off is not amplified by lambda^-k): x_k tends to the lambda-eigencomponent, whose
    # rows are R (tw @ p), with error (|mu| / lambda)^k.
    w = ep.limit_point_weights(d, angles=angles, lengths=lengths)
    x = p - w @ p
    _, gap = eigen_gap(d, angles, lengths)
    k = int(math.ceil(math.log(1e-13) / math.log(gap)))
    for _ in range(k):
        x = m @ x
        x = (x - w @ x) / lam
    right = p0 - c_shift(d, angles, lengths)
    np.testing.assert_allclose(x, right @ (tw @ p), atol=1e-10 * np.abs(x).max())
    # the ring vectors after many steps lie in the tangent plane
    assert np.abs((x - x[0]) @ normal).max() < 1e-10 * np.abs(x).max()


def c_shift(d, angles, lengths):
    c = ep.rule_coefficients(d, angles=angles, lengths=lengths)
    return c.translation / (1.0 - c.lam)


@pytest.mark.parametrize("n", [3, 5, 6])
def test_projector_is_seed002_q(n):
    d = random_intervals(np.random.default_rng(30 + n), n, 4.0)
    m = ep.local_subdivision_matrix(d)
    lam = ep.characteristic_scale(n).lam
    proj = ep.tangent_projector(d)
    # [FSLYJ] step 3 literally: N^ = N[1:,1:] - N[0,1:], eigen-decomposition, keep lambda.
    nhat = m[1:, 1:] - m[0, 1:][None, :]
    vals, u = np.linalg.eig(nhat)
    keep = np.abs(vals - lam) < 1e-8
    assert keep.sum() == 2
    q = (u @ np.diag(keep.astype(float)) @ np.linalg.inv(u)).real
    dmat = np.hstack([-np.ones((2 * n, 1)), np.eye(2 * n)])
    np.testing.assert_allclose(proj, q @ dmat, atol=1e-10)
    # rows lie in the span of the tangent weights
    tw = ep.tangent_weights(d)
    coef, *_ = np.linalg.lstsq(tw.T, proj.T, rcond=None)
    np.testing.assert_allclose(tw.T @ coef, proj.T, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Invariances (hypothesis)

intervals_strategy = st.integers(3, 9).flatmap(
    lambda n: st.lists(st.floats(1.0, 5.0), min_size=n, max_size=n)
)


def relabel(n, shift, reflect):
    """perm[new local index] = old local index for E'_i = E_{s(i)}, F'_i = F_{s'(i)}."""
    perm = [0]
    if not reflect:
        perm += [1 + (i + shift) % n for i in range(n)]
        perm += [1 + n + (i + shift) % n for i in range(n)]
    else:  # spoke i' = spoke -i; face i' (spokes -i, -i-1) = face -i-1
        perm += [1 + (-i) % n for i in range(n)]
        perm += [1 + n + (-i - 1) % n for i in range(n)]
    return np.array(perm)


@settings(max_examples=40, deadline=None)
@given(intervals_strategy, st.integers(0, 8), st.sampled_from(OPTIONS))
def test_rows_sum_to_one_and_rotation_permutes(d, shift, opts):
    angles, lengths = opts
    n = len(d)
    d = np.array(d)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    np.testing.assert_allclose(m.sum(axis=1), 1.0, atol=1e-14)
    m2 = ep.local_subdivision_matrix(np.roll(d, -shift), angles=angles, lengths=lengths)
    perm = relabel(n, shift, False)
    # 1e-12: the cache key rounds intervals to 14 significant digits, then quadratic solves
    np.testing.assert_allclose(m2, m[np.ix_(perm, perm)], atol=1e-12)
    w2 = ep.limit_point_weights(np.roll(d, -shift), angles=angles, lengths=lengths)
    w = ep.limit_point_weights(d, angles=angles, lengths=lengths)
    np.testing.assert_allclose(w2, w[perm], atol=1e-11)


@settings(max_examples=30, deadline=None)
@given(intervals_strategy, st.sampled_from(OPTIONS))
def test_reversing_orientation_permutes(d, opts):
    angles, lengths = opts
    n = len(d)
    d = np.array(d)
    m = ep.local_subdivision_matrix(d, angles=angles, lengths=lengths)
    m2 = ep.local_subdivision_matrix(d[(-np.arange(n)) % n], angles=angles, lengths=lengths)
    perm = relabel(n, 0, True)
    np.testing.assert_allclose(m2, m[np.ix_(perm, perm)], atol=1e-12)


def test_scale_invariance_and_cache():
    d = [1.0, 2.0, 3.5, 1.25, 4.0]
    a = ep.local_subdivision_matrix(d)
    b = ep.local_subdivision_matrix([7 * x for x in d])
    assert a is b  # one cached solution per configuration
    with pytest.raises(ValueError):
        a[0, 0] = 1.0  # read-only: the cache cannot be corrupted


@pytest.mark.parametrize("bad", [[1, 1], [1, 0, 1, 1], [1, -1, 1], [1, float("nan"), 1]])
def test_bad_intervals_raise(bad):
    with pytest.raises(ValueError, match="interval"):
        ep.local_subdivision_matrix(bad)


def test_bad_option_raises():
    with pytest.raises(ValueError, match="angles"):
        ep.local_subdivision_matrix([1, 1, 1], angles="equal")


@pytest.mark.parametrize("angles", ["standard", "modified"])
def test_batch_of_vertices_equals_one_at_a_time(angles):
    """local_subdivision_matrices solves g vertices of one valence in one vectorised call; each
    matrix is the single-vertex one (which rounds its cache key to 14 digits: hence 1e-13 and
    not round-off alone)."""
    rng = np.random.default_rng(31)
    for n in (3, 5, 8):
        d = rng.uniform(1, 5, size=(40, n))
        batch = ep.local_subdivision_matrices(d, angles=angles)
        assert batch.shape == (40, 2 * n + 1, 2 * n + 1)
        for k in range(40):
            np.testing.assert_allclose(batch[k], ep.local_subdivision_matrix(d[k], angles=angles), atol=1e-13)


def test_batch_names_the_vertex_whose_rule_is_undefined():
    bad = [37.1, 93.8, 509.0, 1.8, 166.9, 12.2, 3300.7, 1.8]  # valence 8: face 0 has no root
    with pytest.raises(ValueError, match="face 0"):
        ep.local_subdivision_matrix(bad)
    d = np.ones((6, 8))
    d[4] = bad
    with pytest.raises(ep.BilinearError) as info:
        ep.local_subdivision_matrices(d)
    assert info.value.index == (4, 0)  # vertex 4, face 0
