"""Uniform degree-d subdivision curves (s = 0): operators and the exported exact limit.

References: scipy's BSpline of the control polygon (the uniform B-spline by definition) and
OpenCASCADE's own evaluation of the curve read back from the STEP file.
"""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from scipy.interpolate import BSpline

from patching.curves.curve import Curve
from patching.curves.uniform import uniform_subdivision

DEGREES = range(2, 8)


def _scipy_reference(P: np.ndarray, d: int, closed: bool):
    """The uniform B-spline of the polygon and its domain, in scipy's own parameterisation."""
    n = len(P)
    if closed:
        return BSpline(np.arange(n + 2 * d + 1.0), np.r_[P, P[:d]], d), (d, n + d)
    return BSpline(np.arange(n + d + 1.0), P, d), (d, n)


def _occ_curve_from_step(path):
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from export.ocp_compat import TopoDS

    from export import read_step

    shape = read_step(path)
    explorer = TopExp_Explorer(shape, TopAbs_EDGE)
    edges = []
    while explorer.More():
        edges.append(TopoDS.Edge_s(explorer.Current()))
        explorer.Next()
    assert len(edges) == 1
    curve = BRepAdaptor_Curve(edges[0])
    return curve, curve.FirstParameter(), curve.LastParameter()


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("d", DEGREES)
def test_step_equals_scipy_bspline(tmp_path, d, closed):
    from export.curves import write_curve

    rng = np.random.default_rng(d + 10 * closed)
    n = 11
    P = rng.uniform(-50, 50, size=(n, 3))
    curve = Curve(P, d, closed)
    path = write_curve(curve, tmp_path / "c.step")
    occ, first, last = _occ_curve_from_step(path)
    ref, (a, b) = _scipy_reference(P, d, closed)
    assert last - first == pytest.approx(b - a, abs=1e-12)
    # Parameter shift between the two writings of one curve: open, the domain starts at
    # scipy's knot d; closed, P_i's basis function is centred at parameter i (uniform.py),
    # scipy's at i + (d + 1) / 2, and the exported domain starts at knot d - d//2 - (d+1)/2.
    shift = d if not closed else d - d // 2
    t = np.linspace(first, last, 301)
    ours = np.array([[occ.Value(float(u)).X(), occ.Value(float(u)).Y(), occ.Value(float(u)).Z()] for u in t])
    s = t - first + shift
    if closed:
        s = (s - d) % n + d
    size = np.ptp(P, axis=0).max()
    # 1e-12 of the size: the knot insertions that clamp the curve and OCC's de Boor both
    # round at 1e-16 relative per operation
    assert np.abs(ours - ref(s)).max() <= 1e-12 * size


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("d", DEGREES)
def test_refinement_is_lane_riesenfeld_and_keeps_the_limit(d, closed):
    n = 9
    A = uniform_subdivision(n, d, closed).toarray()
    # every row is the mask binom(d+1, k)/2^d on consecutive points (independent re-derivation:
    # d + 1 rounds of averaging of the doubled polygon, Lane-Riesenfeld)
    e = np.eye(n)
    doubled = np.repeat(e, 2, axis=0)
    Q = doubled.copy()
    for _ in range(d):
        Q = (Q + np.roll(Q, -1, axis=0)) / 2
    # Q's rows are the closed refinement up to a cyclic shift of rows
    if closed:
        matches = [k for k in range(2 * n) if np.allclose(np.roll(Q, k, axis=0), A, atol=1e-15)]
        assert matches
    assert np.allclose(A.sum(axis=1), 1.0, atol=1e-15)
    mask = np.array([comb(d + 1, k) for k in range(d + 2)]) / 2.0**d
    for row in A:
        nz = row[row > 0]
        assert any(len(nz) == len(mask[p::2]) and np.allclose(np.sort(nz), np.sort(mask[p::2])) for p in (0, 1))
    rng = np.random.default_rng(d)
    P = rng.normal(size=(n if closed else n + d, 2))
    c = Curve(P, d, closed)
    fine = c.refine(2)
    t = np.linspace(*c.limit().domain, 97)
    assert np.abs(c.evaluate(t) - fine.evaluate(4 * t)).max() < 1e-13
