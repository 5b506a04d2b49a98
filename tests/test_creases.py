"""Infinitely sharp creases through regular vertices.

Across a crease each face reads a mirrored neighbour (the phantom row 2 P_0 - P_1), and the
crease's edge and vertex points are those of the crease polygon's own cubic B-spline.  With
uniform intervals this is exactly Catmull-Clark's crease limit surface (OpenSubdiv's rules);
with non-uniform ones the crease curve is the non-uniform B-spline of its polygon."""

import numpy as np
import pytest
from OCP.Geom import Geom_BSplineCurve
from OCP.GeomConvert import GeomConvert_BSplineCurveToBezierCurve
from OCP.gp import gp_Pnt
from export.ocp_compat import TColgp_Array1OfPnt
from export.ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal

import patching
from patching.mesh.primitives import torus_grid
from patching.subdivision import limit_points, subdivide
from tests.edge_checks import edge_jumps
from tests.helpers import shared_edge_normal_jumps
from tests.helpers import distances_to_surface

M, N, ROW = 8, 6, 2


def idx(a: int, b: int) -> int:
    return (a % M) * N + (b % N)


def creased_torus(du=None, dv=None, seed=0) -> patching.ControlMesh:
    """An M x N torus with a closed crease along the ring of vertices (ROW, b)."""
    mesh = torus_grid(M, N, du, dv)
    rng = np.random.default_rng(seed)
    points = mesh.vertices + rng.normal(scale=0.05, size=mesh.vertices.shape)
    creases = {(idx(ROW, b), idx(ROW, b + 1)): np.inf for b in range(N)}
    return patching.from_arrays(points, mesh.quads(), intervals=dict(mesh.intervals), creases=creases, name="creased")


def test_uniform_crease_is_catmull_clarks_crease_limit_surface():
    mesh = creased_torus()
    surface = patching.build(mesh)
    refined = subdivide(mesh, 3, rules="opensubdiv")
    worst = distances_to_surface(surface, limit_points(refined)).max()
    # Gauss-Newton converges to round-off on these bicubic patches.
    assert worst <= 1e-12 * surface.size


@pytest.mark.parametrize("seed", [0, 1])
def test_non_uniform_crease_curve_is_the_bspline_of_its_polygon(seed):
    rng = np.random.default_rng(seed)
    du, dv = rng.uniform(1, 20, M), rng.uniform(1, 20, N)
    mesh = creased_torus(du, dv, seed)
    surface = patching.build(mesh)
    # OCC's periodic cubic B-spline of the crease polygon, knots from the crease strip's
    # intervals (docs/knots.md: pole l is P[(l - 2) mod N]).
    poles = TColgp_Array1OfPnt(1, N)
    for l in range(1, N + 1):
        poles.SetValue(l, gp_Pnt(*map(float, mesh.vertices[idx(ROW, (l - 2) % N)])))
    knots = np.concatenate([[0.0], np.cumsum(dv)])
    k = TColStd_Array1OfReal(1, N + 1)
    mult = TColStd_Array1OfInteger(1, N + 1)
    for i, x in enumerate(knots):
        k.SetValue(i + 1, float(x))
        mult.SetValue(i + 1, 1)
    curve = Geom_BSplineCurve(poles, k, mult, 3, True)
    conv = GeomConvert_BSplineCurveToBezierCurve(curve)
    segments = []
    for i in range(1, conv.NbArcs() + 1):
        arc = conv.Arc(i)
        segments.append(np.array([[arc.Pole(j).X(), arc.Pole(j).Y(), arc.Pole(j).Z()] for j in range(1, 5)]))
    # Every patch side lying on the crease is one of those segments (either direction).
    crease_faces = 0
    for _, _, face, net in surface.patches():
        a = face // N
        if a not in (ROW - 1, ROW):
            continue
        side = net[3, :] if a == ROW - 1 else net[0, :]  # the side on the row a = ROW
        best = min(min(np.abs(seg - side).max(), np.abs(seg[::-1] - side).max()) for seg in segments)
        assert best <= 1e-12 * surface.size
        crease_faces += 1
    assert crease_faces == 2 * N


def test_creased_torus_is_a_valid_solid_c0_on_the_crease_and_g1_elsewhere():
    from export import check_continuity, to_shape

    rng = np.random.default_rng(4)
    mesh = creased_torus(rng.uniform(1, 5, M), rng.uniform(1, 5, N))
    surface = patching.build(mesh)
    report = check_continuity(to_shape(surface))
    assert report.valid and report.n_solids == 1 and report.n_free_edges == 0
    assert report.max_gap_relative <= 1e-12
    assert report.max_normal_jump_deg > 5.0  # the crease is a real C0 angle
    # every edge off the crease is G1 (numpy check, crease sides excluded)
    smooth = patching.build(torus_grid(M, N, rng.uniform(1, 5, M), rng.uniform(1, 5, N)))
    assert shared_edge_normal_jumps(smooth)[0] <= 1e-7
    _, _, angles, sharp = edge_jumps(mesh, surface)  # every edge off the crease, by the tags
    assert sharp.sum() == N and angles[~sharp].max() <= 1e-7
