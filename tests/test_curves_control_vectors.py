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


# ---------------------------------------------------------------- corners and vectors together
def _dfold(knots, d):
    """Interior knot values of multiplicity >= d."""
    vals, counts = np.unique(knots, return_counts=True)
    keep = (counts >= d) & (vals > knots[0]) & (vals < knots[-1])
    return set(float(x) for x in vals[keep])


def _vector_knot(P, d, closed, corners, v):
    """Where the vector at v sits on the cornered curve: the d-fold knot that an infinitely
    sharp vector adds to the corner limit (found from the knots, not from the code's rule)."""
    V = np.ones(P.shape[1])
    added = _dfold(Curve(P, d, closed, corners=corners, vectors={v: (V, math.inf)}).limit().knots, d) - _dfold(
        Curve(P, d, closed, corners=corners).limit().knots, d)
    (t,) = added
    return t


def _uniform_vector_function(d, V, s):
    """The vector's function on a uniform curve of zero points (no corners, [KSD] eq. (11)),
    as a function of the offset from its crease knot."""
    Z = np.zeros((12 * d, len(V)))
    v = 6 * d
    f = Curve(Z, d, vectors={v: (V, s)}).limit()
    (t0,) = _dfold(Curve(Z, d, vectors={v: (V, math.inf)}).limit().knots, d)
    return lambda x: f.evaluate(t0 + x)


def test_vector_with_sharp_ends_starts_and_ends_at_the_end_vertices():
    """The bug this fixes: vectors made the curve ignore its end tags (free ends, n - d spans)."""
    rng = np.random.default_rng(5)
    n, d = 14, 3
    P = rng.normal(size=(n, 2))
    ends = {0: math.inf, n - 1: math.inf}
    c = Curve(P, d, corners=ends, vectors={7: (np.array([0.5, 1.0]), math.inf)}).limit()
    assert c.domain == Curve(P, d, corners=ends).limit().domain
    assert np.abs(c.evaluate(c.domain[0]) - P[0]).max() < 1e-13
    assert np.abs(c.evaluate(c.domain[1]) - P[-1]).max() < 1e-13


def _cases():
    for d in range(2, 8):
        for closed in (False, True):
            for cs in (math.inf, 1.0, 2.5 if d % 2 else 2.0):
                for vs in (math.inf, 2.0):
                    yield d, closed, cs, vs


@pytest.mark.parametrize("d,closed,cs,vs", list(_cases()))
def test_corners_and_a_vector_superpose_at_the_clearance(d, closed, cs, vs):
    """A vector VECTOR_CLEARANCE[d] edges from a semi-sharp corner (on either side), the open
    polygon's ends sharp: the curve minus the vector-free curve is exactly the vector's function
    of the uniform curve (Table 1's crease function refined s times), so (a) nothing changes
    outside its 2 floor(d/2) spans, (b) it is linear in the vector."""
    from patching.curves.curve import VECTOR_CLEARANCE

    rng = np.random.default_rng(d * 100 + int(closed))
    gap = VECTOR_CLEARANCE[d]
    u = 2 * gap + 2
    n = 2 * u + 1
    P = rng.normal(size=(n, 2))
    corners = {u: cs} if closed else {0: math.inf, n - 1: math.inf, u: cs}
    base = Curve(P, d, closed, corners=corners).limit()
    V1, V2 = rng.normal(size=2), rng.normal(size=2)
    w = d // 2
    for v in (u - gap, u + gap):
        tj = _vector_knot(P, d, closed, corners, v)
        t = np.linspace(*base.domain, 60 * n + 1)
        g1 = Curve(P, d, closed, corners=corners, vectors={v: (V1, vs)}).evaluate(t) - base.evaluate(t)
        g2 = Curve(P, d, closed, corners=corners, vectors={v: (V2, vs)}).evaluate(t) - base.evaluate(t)
        g12 = Curve(P, d, closed, corners=corners, vectors={v: (V1 + 2 * V2, vs)}).evaluate(t) - base.evaluate(t)
        outside = np.abs(t - tj) > w + 1e-9
        assert np.abs(g1[outside]).max() < 1e-13  # (a)
        assert np.abs(g1[~outside]).max() > 1e-6
        assert np.abs(g12 - g1 - 2 * g2).max() < 1e-12  # (b)
        ref = _uniform_vector_function(d, V1, vs)(t[~outside] - tj)
        assert np.abs(g1[~outside] - ref).max() < 1e-12


@pytest.mark.parametrize("d", [3, 4, 5])
def test_refined_curve_with_corners_and_vectors_has_the_same_limit(d):
    from patching.curves.curve import VECTOR_CLEARANCE

    rng = np.random.default_rng(d)
    gap = VECTOR_CLEARANCE[d]
    n = 3 * gap + 4
    P = rng.normal(size=(n, 3))
    corners = {0: math.inf, n - 1: math.inf, n - 1 - gap - 1: 1.0 if d % 2 == 0 else 1.5}
    c = Curve(P, d, corners=corners, vectors={gap: (rng.normal(size=3), 2.0)})
    lim = c.limit()
    t = np.linspace(*lim.domain, 301)
    for k in (1, 2, 3):
        ck = c.refine(k)
        assert np.abs(ck.limit().evaluate(t * 2**k) - lim.evaluate(t)).max() < 1e-12


def test_corner_and_vector_refusals():
    from patching.curves.curve import VECTOR_CLEARANCE
    from patching.errors import TagError, UnsupportedError

    P = np.random.default_rng(0).normal(size=(20, 2))
    V = np.array([1.0, 0.0])
    with pytest.raises(TagError, match="vertex 8 has both a corner tag and a control vector"):
        Curve(P, 3, corners={8: 2.0}, vectors={8: (V, 1.0)})
    gap = VECTOR_CLEARANCE[3]
    with pytest.raises(UnsupportedError, match=f"tagged vertex 0: degree 3 needs {gap}") as e:
        Curve(P, 3, corners={0: math.inf}, vectors={gap - 1: V})
    assert f"vertex {gap - 1}" in str(e.value) and "\n" not in str(e.value)
    Curve(P, 3, corners={0: math.inf}, vectors={gap: V}).limit()  # at the clearance: fine
    with pytest.raises(UnsupportedError, match="fractional corner sharpness at even degree 4"):
        Curve(P, 4, corners={3: 1.5}, vectors={12: V})


def test_step_of_a_clamped_curve_with_a_vector_equals_evaluate(tmp_path):
    """(c): the STEP file of both clamped ends and an interior vector, read back with OCC."""
    pytest.importorskip("OCP")
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    from export import read_step
    from export.curves import write_curve
    from export.ocp_compat import TopoDS

    rng = np.random.default_rng(9)
    for d in (3, 4):
        n = 16
        P = rng.normal(size=(n, 3)) * 10
        c = Curve(P, d, corners={0: math.inf, n - 1: math.inf}, vectors={8: (rng.normal(size=3), math.inf)})
        out = tmp_path / f"c{d}.step"
        write_curve(c, out)
        ex = TopExp_Explorer(read_step(out), TopAbs_EDGE)
        edge = BRepAdaptor_Curve(TopoDS.Edge_s(ex.Current()))
        ex.Next()
        assert not ex.More()
        lim = c.limit()
        assert (edge.FirstParameter(), edge.LastParameter()) == pytest.approx(lim.domain, abs=1e-12)
        t = np.linspace(*lim.domain, 401)
        occ = np.array([[edge.Value(float(x)).X(), edge.Value(float(x)).Y(), edge.Value(float(x)).Z()] for x in t])
        size = float(np.abs(P).max())
        assert np.abs(occ - lim.evaluate(t)).max() < 1e-12 * size
        assert np.abs(occ[0] - P[0]).max() < 1e-12 * size and np.abs(occ[-1] - P[-1]).max() < 1e-12 * size
