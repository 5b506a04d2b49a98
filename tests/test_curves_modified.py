"""The modified quintic T~5 ([KSD] sec. 3.2.2, eq. (7)) exported by refinement to a tolerance:
the B-spline against the deeply refined T~5 polygon, and the command."""

from __future__ import annotations

import math

import numpy as np

from patching.curves.curve import Curve, ModifiedQuinticCurve, modified_quintic_limit
from tests.test_curves_export import G_OBJ


def test_the_b_spline_is_within_tolerance_of_the_refined_t5_tilde_polygon():
    """12 steps of T~5 (h = 2^-12: the polygon is within ~1e-8 of its limit) against the
    B-spline at the points' parameters (point i of level L sits at i / 2^L): within the
    tolerance; the exact T5 curve of the same polygon is not (so the refinement mattered)."""
    rng = np.random.default_rng(4)
    P = rng.normal(size=(11, 2))
    corners = {3: math.inf, 6: 1.5, 8: 0.5}
    tol = 1e-4
    fit = modified_quintic_limit(P, False, corners, tol)
    assert fit.error <= tol and fit.steps >= 2
    L = 12
    deep = ModifiedQuinticCurve(P, False, corners).refine(L).points
    t = np.arange(len(deep)) / 2.0**L
    dist = np.linalg.norm(fit.curve.evaluate(t) - deep, axis=1)
    assert dist.max() <= tol
    t5 = Curve(P, 5, corners={**corners, 0: math.inf, 10: math.inf}).evaluate(t)
    assert np.linalg.norm(t5 - deep, axis=1).max() > 10 * tol
    # a tighter tolerance takes more steps and comes closer
    tight = modified_quintic_limit(P, False, corners, tol / 100)
    assert tight.steps > fit.steps
    assert np.linalg.norm(tight.curve.evaluate(t) - deep, axis=1).max() < tol / 50


def test_curve_modified_writes_step_within_tolerance(tmp_path, run_cli):
    from tests.test_curves_export import _occ_edges, _xyz

    src = tmp_path / "g.obj"
    src.write_text(G_OBJ)
    out = tmp_path / "g.step"
    r = run_cli("curve", src, "-d", "5", "--modified", "--tolerance", "1e-3", "-o", out)
    assert r.returncode == 0, r.stderr
    (edge,) = _occ_edges(out)
    from patching.curves.polyline import read_polyline

    poly = read_polyline(src)
    deep = ModifiedQuinticCurve(poly.points, False, poly.corners).refine(10).points
    u = np.linspace(edge.FirstParameter(), edge.LastParameter(), len(deep))
    got = np.array([_xyz(edge, x) for x in u])
    assert np.linalg.norm(got - deep, axis=1).max() <= 1e-3 + 1e-9
