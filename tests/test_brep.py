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
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID, TopAbs_VERTEX
from OCP.TopExp import TopExp
from export.ocp_compat import TopoDS
from export.ocp_compat import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape

from export.brep import BrepError, to_shape
from patching.surface import BezierSurface, PatchTopology
from tests.helpers import CUBE_QUADS, count, cube_surface as cube, edges_of, net_volume, seam_tube, single_patch, torus_surface as torus, volume

# --------------------------------------------------------------------------- surfaces by hand


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


def test_a_bad_net_is_named_by_its_patch_and_face():
    """The nets are checked a group at a time; the message names the first bad patch in row
    order and its face, as a patch-by-patch check would."""
    import dataclasses

    surf = cube((3, 3, 5, 5, 3, 5))  # groups of degree 3 and 5: rows 0-2 and 3-5
    g = surf.groups[1]
    nets = g.coefficients.copy()
    nets[2, 1, 4, 0] = np.nan
    bad = dataclasses.replace(surf, groups=(surf.groups[0], dataclasses.replace(g, coefficients=nets)) + surf.groups[2:])
    row = len(surf.groups[0].faces) + 2
    with pytest.raises(BrepError, match=rf"^patch {row} \(face {int(g.faces[2])}\): non-finite coefficients$"):
        to_shape(bad)
    listed = dataclasses.replace(g, coefficients=[np.zeros((6, 6, 3)), np.zeros((4, 4, 3)), np.zeros((6, 6, 3))])
    odd = dataclasses.replace(surf, groups=(surf.groups[0], listed) + surf.groups[2:])
    with pytest.raises(BrepError, match=rf"^patch {len(surf.groups[0].faces) + 1} \(face {int(g.faces[1])}\): net shape \(4, 4, 3\), degree 5$"):
        to_shape(odd)
