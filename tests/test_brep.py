"""export.brep: hand-built Bézier surfaces to OCC B-reps with shared topology.

The helpers at the top build ``BezierSurface`` objects without ``patching`` (so these tests
do not depend on it) and are imported by test_step.py and test_continuity.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID, TopAbs_VERTEX
from OCP.TopExp import TopExp
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape

from export.brep import BrepError, to_shape
from patching.surface import BezierSurface, PatchGroup, PatchTopology

# --------------------------------------------------------------------------- surfaces by hand


def topology_from_quads(quads) -> PatchTopology:
    """Shared corners and sides of quads given by vertex ids (v0 v1 v2 v3, counter-clockwise).

    Edge ids in order of first use (row, then side); an edge's own direction is its first side's.
    """
    quads = np.asarray(quads, dtype=np.int64)
    side_edge = np.zeros(quads.shape, np.int64)
    side_reversed = np.zeros(quads.shape, bool)
    edges: dict[tuple[int, int], tuple[int, tuple[int, int]]] = {}
    for r, quad in enumerate(quads):
        for k in range(4):
            a, b = int(quad[k]), int(quad[(k + 1) % 4])
            eid, own = edges.setdefault((min(a, b), max(a, b)), (len(edges), (a, b)))
            side_edge[r, k] = eid
            side_reversed[r, k] = own != (a, b)
    return PatchTopology(quads, side_edge, side_reversed, int(quads.max()) + 1, len(edges))


def elevate(net: np.ndarray, degree: int) -> np.ndarray:
    """Degree-elevate a (d+1, d+1, 3) Bézier net to ``degree`` in both directions (exact)."""
    for _ in range(degree - (net.shape[0] - 1)):
        for axis in (0, 1):
            net = np.moveaxis(net, axis, 0)
            n = net.shape[0] - 1  # b'_i = i/(n+1) b_{i-1} + (1 - i/(n+1)) b_i
            a = (np.arange(n + 2) / (n + 1))[:, None, None]
            lower = np.concatenate([net[:1], net])
            upper = np.concatenate([net, net[-1:]])
            net = np.moveaxis(a * lower + (1 - a) * upper, 0, axis)
    return net


def surface(quads, nets, degrees=None, name="test") -> BezierSurface:
    """A BezierSurface from per-quad nets (any degrees), one PatchGroup per degree."""
    nets = list(nets)
    degrees = [n.shape[0] - 1 for n in nets] if degrees is None else list(degrees)
    nets = [elevate(n, d) for n, d in zip(nets, degrees)]
    quads = np.asarray(quads)
    order = sorted(range(len(nets)), key=lambda r: degrees[r])  # rows follow the groups
    groups = tuple(
        PatchGroup(d, np.array([r for r in order if degrees[r] == d]), np.array([nets[r] for r in order if degrees[r] == d]))
        for d in sorted(set(degrees))
    )
    points = np.concatenate([n.reshape(-1, 3) for n in nets])
    size = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    return BezierSurface(groups, topology_from_quads(quads[order]), name, size)


def bilinear_net(corners, degree: int = 3) -> np.ndarray:
    """The bilinear patch on 4 corners (v0 v1 v2 v3) as a degree-``degree`` net."""
    c = np.asarray(corners, float)
    s = np.linspace(0.0, 1.0, degree + 1)[:, None, None]
    t = np.linspace(0.0, 1.0, degree + 1)[None, :, None]
    return (1 - s) * (1 - t) * c[0] + s * (1 - t) * c[1] + s * t * c[2] + (1 - s) * t * c[3]


CUBE_VERTICES = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float
)
#: Counter-clockwise seen from outside, so S_s x S_t points out.
CUBE_QUADS = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def cube(degrees=(3,) * 6, quads=CUBE_QUADS) -> BezierSurface:
    """The unit cube: 6 flat patches (bilinear, degree-elevated), 8 vertices, 12 edges."""
    return surface(quads, [bilinear_net(CUBE_VERTICES[q], 1) for q in quads], degrees, "cube")


#: Uniform cubic B-spline segment to Bézier: (b0..b3) = BSPLINE_TO_BEZIER @ (P0..P3).
BSPLINE_TO_BEZIER = np.array([[1, 4, 1, 0], [0, 4, 2, 0], [0, 2, 4, 0], [0, 1, 4, 1]]) / 6.0


def torus(m: int = 8, n: int = 6, degrees=None, big: float = 3.0, small: float = 1.0) -> BezierSurface:
    """Periodic uniform bicubic B-spline on an m x n torus grid, as m*n Bézier patches: C2.

    Patch (i, j) is row i*n + j (when all degrees are equal), s along i, t along j.
    """
    u = 2 * np.pi * np.arange(m) / m
    v = 2 * np.pi * np.arange(n) / n
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ring = big + small * np.cos(vv)
    grid = np.stack([ring * np.cos(uu), ring * np.sin(uu), small * np.sin(vv)], axis=-1)
    quads, nets = [], []
    for i in range(m):
        for j in range(n):
            local = grid[np.ix_((np.arange(4) + i - 1) % m, (np.arange(4) + j - 1) % n)]
            nets.append(np.einsum("ia,jb,abx->ijx", BSPLINE_TO_BEZIER, BSPLINE_TO_BEZIER, local))
            vid = [((i + a) % m) * n + (j + b) % n for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))]
            quads.append(vid)
    return surface(quads, nets, degrees, "torus")


def single_patch(degree: int = 3) -> BezierSurface:
    """One open, curved patch."""
    s = np.linspace(0, 1, degree + 1)
    ss, tt = np.meshgrid(s, s, indexing="ij")
    net = np.stack([ss, tt, 0.3 * np.sin(3 * ss) * tt], axis=-1)
    return surface([[0, 1, 2, 3]], [net], name="patch")


def seam_tube() -> BezierSurface:
    """One bi-quintic patch closed on itself in s: its sides 1 and 3 are one (seam) edge.

    The s-rows follow a C1 closed quintic loop (P5 = P0, P5 - P4 = P1 - P0); corners 0, 1
    are one vertex and so are 2, 3, so sides 0 and 2 are closed edges.
    """
    loop = np.array([[0, 0], [1, 0], [2, 2], [-2, 2], [-1, 0], [0, 0]], float)
    height = np.linspace(0.0, 1.0, 6)
    net = np.stack(np.broadcast_arrays(loop[:, None, 0], loop[:, None, 1], height[None, :]), axis=-1)
    return surface([[0, 0, 1, 1]], [net], name="tube")


def volume(shape) -> float:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return props.Mass()


def bernstein(d: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(len(x), d+1) values B_i^d(x) and derivatives."""
    from math import comb

    i = np.arange(d + 1)
    x = np.asarray(x, float)[:, None]
    b = np.array([comb(d, k) for k in i]) * x**i * (1 - x) ** (d - i)
    lower = np.array([comb(d - 1, k) for k in range(d)]) * x ** i[:-1] * (1 - x) ** (d - 1 - i[:-1])
    db = d * (np.pad(lower, ((0, 0), (1, 0))) - np.pad(lower, ((0, 0), (0, 1))))
    return b, db


def net_volume(surf: BezierSurface) -> float:
    """Enclosed volume 1/3 sum over patches of the integral of S . (S_s x S_t), by Gauss-Legendre.

    The integrand has degree <= 3d - 1 in each variable, so 10 nodes (exact to degree 19)
    integrate it exactly for d <= 5: an independent reference for BRepGProp.
    """
    x, w = np.polynomial.legendre.leggauss(10)
    x, w = (x + 1) / 2, w / 2
    total = 0.0
    for group in surf.groups:
        b, db = bernstein(group.degree, x)
        for net in group.coefficients:
            p = np.einsum("ai,bj,ijx->abx", b, b, net)
            ps = np.einsum("ai,bj,ijx->abx", db, b, net)
            pt = np.einsum("ai,bj,ijx->abx", b, db, net)
            total += np.einsum("a,b,abx,abx->", w, w, p, np.cross(ps, pt)) / 3
    return float(total)


def count(shape, kind) -> int:
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, kind, found)
    return found.Extent()


def edges_of(shape):
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_EDGE, found)
    return [TopoDS.Edge_s(found.FindKey(i)) for i in range(1, found.Extent() + 1)]


def first_face(shape):
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, found)
    return TopoDS.Face_s(found.FindKey(1))


# --------------------------------------------------------------------------- tests

MIXED = (3, 5, 3, 5, 5, 3)


@pytest.mark.parametrize("degrees", [(3,) * 6, (5,) * 6, MIXED], ids=["bicubic", "biquintic", "mixed"])
def test_cube_is_a_valid_solid_with_shared_topology(degrees):
    shape = to_shape(cube(degrees))
    assert shape.ShapeType() == TopAbs_SOLID
    assert BRepCheck_Analyzer(shape).IsValid()
    assert (count(shape, TopAbs_SHELL), count(shape, TopAbs_FACE)) == (1, 6)
    assert (count(shape, TopAbs_EDGE), count(shape, TopAbs_VERTEX)) == (12, 8)
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    assert all(edge_faces.FindFromIndex(i).Size() == 2 for i in range(1, 13))
    # The faces are flat, so Gauss integration is exact up to round-off in ~100 terms of size 1.
    assert volume(shape) == pytest.approx(1.0, abs=1e-13)
    assert net_volume(cube(degrees)) == pytest.approx(1.0, abs=1e-13)


def test_inside_out_cube_is_reoriented_to_positive_volume():
    inverted = [q[::-1] for q in CUBE_QUADS]
    shape = to_shape(cube(quads=inverted))
    assert BRepCheck_Analyzer(shape).IsValid()
    assert volume(shape) == pytest.approx(1.0, abs=1e-13)


def test_single_open_patch_gives_a_shell():
    shape = to_shape(single_patch())
    assert shape.ShapeType() == TopAbs_SHELL
    assert BRepCheck_Analyzer(shape).IsValid()
    assert (count(shape, TopAbs_FACE), count(shape, TopAbs_EDGE), count(shape, TopAbs_VERTEX)) == (1, 4, 4)


def test_patch_closed_on_itself_gets_a_seam_edge():
    surf = seam_tube()
    assert surf.topology.side_edge[0, 1] == surf.topology.side_edge[0, 3]
    shape = to_shape(surf)
    assert shape.ShapeType() == TopAbs_SHELL
    assert BRepCheck_Analyzer(shape).IsValid()
    assert (count(shape, TopAbs_FACE), count(shape, TopAbs_EDGE), count(shape, TopAbs_VERTEX)) == (1, 3, 2)
    face = first_face(shape)
    assert sum(BRep_Tool.IsClosed_s(e, face) for e in edges_of(shape)) == 1  # two pcurves on the face


@pytest.mark.parametrize("degrees", [None, [3, 5] * 24], ids=["bicubic", "mixed"])
def test_torus_is_a_valid_solid(degrees):
    surf = torus(degrees=degrees)
    shape = to_shape(surf)
    assert shape.ShapeType() == TopAbs_SOLID
    assert BRepCheck_Analyzer(shape).IsValid()
    assert count(shape, TopAbs_FACE) == 48
    assert count(shape, TopAbs_EDGE) == surf.topology.n_edges == 96
    assert count(shape, TopAbs_VERTEX) == surf.topology.n_vertices == 48
    # Two quadratures of the same polynomial integrand: round-off of ~1e3 terms of size ~30 (measured 6e-16).
    assert volume(shape) == pytest.approx(net_volume(surf), rel=1e-14)


def test_pcurves_are_same_parameter_to_round_off():
    """Surface(pcurve(w)) equals the edge curve(w) on every face, for both edge directions."""
    surf = torus(degrees=[3, 5] * 24)
    shape = to_shape(surf)
    edge_faces = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
    worst = 0.0
    for i in range(1, edge_faces.Extent() + 1):
        edge = TopoDS.Edge_s(edge_faces.FindKey(i))
        assert BRep_Tool.SameParameter_s(edge) and BRep_Tool.SameRange_s(edge)
        curve = BRepAdaptor_Curve(edge)
        assert (curve.FirstParameter(), curve.LastParameter()) == (0.0, 1.0)
        for face in edge_faces.FindFromIndex(i):
            face = TopoDS.Face_s(face)
            pcurve, surface_ = BRepAdaptor_Curve2d(edge, face), BRepAdaptor_Surface(face)
            for w in np.linspace(0.0, 1.0, 7):
                uv = pcurve.Value(w)
                worst = max(worst, surface_.Value(uv.X(), uv.Y()).Distance(curve.Value(w)))
    # Both sides evaluate the same polynomial (degree-elevated or not) in different bases:
    # a few ulps of the coordinates (size ~ 10).
    assert worst < 1e-14 * surf.size


def test_inconsistent_boundary_is_rejected_by_brepcheck():
    surf = torus()
    net = surf.groups[0].coefficients[7]
    net[1:-1, 0] += [0.0, 0.0, 1e-3]  # side 0's interior boundary points: neighbours disagree
    with pytest.raises(BrepError, match="BRepCheck_Analyzer"):
        to_shape(surf)
    assert not BRepCheck_Analyzer(to_shape(surf, check=False)).IsValid()


def test_malformed_topology_is_reported():
    good = cube()
    bad = BezierSurface(good.groups, PatchTopology(
        good.topology.corner_vertex[:5], good.topology.side_edge, good.topology.side_reversed, 8, 12
    ), "cube", good.size)
    with pytest.raises(BrepError, match="corner_vertex"):
        to_shape(bad)
    corners = good.topology.corner_vertex.copy()
    corners[4, 1] = 0  # face 4's side 0 no longer joins the vertices of its edge
    bad = BezierSurface(good.groups, PatchTopology(
        corners, good.topology.side_edge, good.topology.side_reversed, 8, 12
    ), "cube", good.size)
    with pytest.raises(BrepError, match="patch 4 side 0 runs between vertices"):
        to_shape(bad)


def test_first_side_may_run_against_its_edge():
    """Edge direction follows side_reversed even where the contract's 'first side' rule is broken."""
    good = cube()
    topo = good.topology
    flipped = topo.side_edge == topo.side_edge[0, 0]
    bad_rule = PatchTopology(topo.corner_vertex, topo.side_edge, topo.side_reversed ^ flipped, 8, 12)
    shape = to_shape(BezierSurface(good.groups, bad_rule, "cube", good.size))
    assert volume(shape) == pytest.approx(1.0, abs=1e-13)
