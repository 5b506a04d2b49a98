"""``nupatch curve`` and export.curves: STEP/IGES/DXF of the exact limit, OBJ/SVG polygons,
CAD objects, and the one-line errors of bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import BSpline

from patching.curves.curve import Curve

G_OBJ = """\
# a zig-zag with a sharp start, a semi-sharp and a sharp interior vertex
v 0 0 0
v 10 0 0
v 20 10 0
v 30 0 0
v 40 10 0
v 50 0 0
v 60 10 0
v 70 0 0
v 80 10 0
v 90 0 0
l 1 2 3 4 5 6 7 8 9 10
t corner 1/1/0 0 inf
t corner 1/1/0 3 2.5
t corner 1/1/0 6 inf
"""


def _occ_edges(path):
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from export.ocp_compat import TopoDS

    from export import read_step

    explorer = TopExp_Explorer(read_step(path), TopAbs_EDGE)
    out = []
    while explorer.More():
        out.append(BRepAdaptor_Curve(TopoDS.Edge_s(explorer.Current())))
        explorer.Next()
    return out


def _xyz(c, u):
    p = c.Value(float(u))
    return [p.X(), p.Y(), p.Z()]


@pytest.mark.parametrize("d", [3, 5, 4])
def test_dxf_splines_equal_the_step_curve(tmp_path, run_cli, d):
    ezdxf = pytest.importorskip("ezdxf")
    src = tmp_path / "g.obj"
    text = G_OBJ if d % 2 else G_OBJ.replace("t corner 1/1/0 3 2.5\n", "")
    src.write_text(text)
    if d == 3:  # once through the command line, the other degrees through the Python API
        for suffix in ("step", "dxf"):
            r = run_cli("curve", src, "-d", d, "-o", tmp_path / f"g.{suffix}")
            assert r.returncode == 0, r.stderr
    else:
        from export.curves import write_curve
        from patching.curves.polyline import read_polyline

        poly = read_polyline(src)
        for suffix in ("step", "dxf"):
            write_curve(Curve(poly.points, d, corners=poly.corners), tmp_path / f"g.{suffix}")
    (edge,) = _occ_edges(tmp_path / "g.step")
    doc = ezdxf.readfile(tmp_path / "g.dxf")
    splines = doc.modelspace().query("SPLINE")
    assert len(splines) == 2  # one per smooth run: the sharp vertex 6 splits the curve
    start = edge.FirstParameter()
    for sp in splines:
        assert sp.dxf.degree == d
        assert not sp.weights or len(set(sp.weights)) == 1
        P = np.array(sp.control_points)
        K = np.array(sp.knots)
        assert len(K) == len(P) + d + 1
        t = np.linspace(K[0], K[-1], 101)
        ours = BSpline(K, P, d)(t)  # the DXF's own data, evaluated independently of ezdxf
        ref = np.array([_xyz(edge, u) for u in t])
        assert np.abs(ours - ref).max() < 1e-12 * 90  # round-off of the export's knot insertions
        assert K[0] >= start - 1e-12


def test_step_iges_curve_readback(tmp_path, run_cli):
    from OCP.IGESControl import IGESControl_Reader

    src = tmp_path / "g.obj"
    src.write_text(G_OBJ)
    r = run_cli("curve", src, "-d", "5", "-o", tmp_path / "g.iges")
    assert r.returncode == 0, r.stderr
    reader = IGESControl_Reader()
    assert reader.ReadFile(str(tmp_path / "g.iges")) == 1
    assert reader.TransferRoots() >= 1
    from export.curves import write_curve
    from patching.curves.polyline import read_polyline

    poly = read_polyline(src)
    # degree 7 needs more than 4 points from vertex 6 to a free end: tag the end sharp
    write_curve(Curve(poly.points, 7, corners={**poly.corners, 9: math.inf}), tmp_path / "g.step")
    (edge,) = _occ_edges(tmp_path / "g.step")
    # the curve starts at the sharp end vertex and passes through the sharp vertex 6
    from OCP.GeomAbs import GeomAbs_BSplineCurve

    assert edge.GetType() == GeomAbs_BSplineCurve
    assert edge.BSpline().Degree() == 7
    mults = [edge.BSpline().Multiplicity(i) for i in range(1, edge.BSpline().NbKnots() + 1)]
    assert mults[0] == mults[-1] == 8 and mults.count(7) == 1  # C0 only at vertex 6
    assert np.allclose(_xyz(edge, edge.FirstParameter()), [0, 0, 0], atol=1e-12)
    assert np.allclose(_xyz(edge, 6.0), [60, 10, 0], atol=1e-10)


def test_obj_and_svg_polygons(tmp_path, run_cli):
    from patching.curves.polyline import read_polyline

    src = tmp_path / "g.obj"
    src.write_text(G_OBJ)
    r = run_cli("curve", src, "-d", "3", "-o", tmp_path / "out.obj", "-n", "2")
    assert r.returncode == 0, r.stderr
    back = read_polyline(tmp_path / "out.obj")
    ref = Curve(read_polyline(src).points, 3, corners={0: math.inf, 3: 2.5, 6: math.inf}).refine(2)
    assert np.allclose(back.points, ref.points, atol=1e-15)
    # the remaining sharpness is written back: 2.5 - 2 = 0.5 at the child of vertex 3
    assert back.corners[12] == pytest.approx(0.5) and back.corners[24] == math.inf
    from export.curves import write_curve

    one = Curve(read_polyline(src).points, 3, corners={0: math.inf, 3: 2.5, 6: math.inf})
    write_curve(one, tmp_path / "out.svg", steps=1)
    svg = (tmp_path / "out.svg").read_text()
    assert "<polyline" in svg and svg.count(",") == len(one.refine(1).points)


def test_build123d_edge_sweeps_a_circle_into_a_valid_solid():
    bd = pytest.importorskip("build123d")
    import export

    P = np.array([[0, 0, 0], [10, 0, 0], [20, 10, 0], [30, 0, 5], [40, 10, 0], [50, 0, 0]], float)
    curve = Curve(P, 5, corners={0: math.inf, 5: math.inf, 2: 1.5})
    edge = export.to_build123d(curve)
    assert isinstance(edge, bd.Edge)
    assert np.allclose(tuple(edge @ 0), P[0]) and np.allclose(tuple(edge @ 1), P[-1])
    profile = bd.Plane(origin=edge @ 0, z_dir=edge % 0) * bd.Circle(1.0)
    solid = bd.sweep(profile, path=edge)
    assert solid.is_valid
    assert len(solid.solids()) == 1
    # a thin tube: volume pi r^2 L to the curvature term (r / radius of curvature ~ 1e-2)
    assert solid.volume == pytest.approx(math.pi * edge.length, rel=2e-2)
    wire = export.to_cadquery(curve)
    assert wire.isValid()
    assert np.allclose(wire.startPoint().toTuple(), P[0]) and np.allclose(wire.endPoint().toTuple(), P[-1])


BAD = {
    "one vertex": ("v 0 0 0\nl 1\n", [], "at least 2"),
    "degree 1": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nl 1 2 3\n", ["-d", "1"], "degree 1"),
    "degree 8": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nl 1 2 3\n", ["-d", "8"], "degree 8"),
    "NaN sharpness": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 3 0 0\nv 4 0 1\nl 1 2 3 4 5\nt corner 1/1/0 2 nan\n", [], "NaN"),
    "negative sharpness": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 3 0 0\nv 4 0 1\nl 1 2 3 4 5\nt corner 1/1/0 2 -1\n", [], "negative"),
    "vector on a missing vertex": (
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 3 0 0\nv 4 0 1\nl 1 2 3 4 5\nt controlvector 1/3/0 9 0 1 0\n", [], "vertex 9"),
    "no polyline": ("v 0 0 0\nv 1 0 0\n", [], "no polyline"),
    "modified not quintic": (G_OBJ, ["-d", "3", "--modified"], "-d 5"),
    "modified tolerance": (G_OBJ, ["-d", "5", "--modified", "--tolerance", "-1"], "positive"),
    # even degree: a fractional sharpness has an exact limit (STEP/IGES/DXF) but no polygon
    "fractional even, polygon": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 3 0 0\nv 4 0 1\nv 5 0 0\nv 6 1 0\nl 1 2 3 4 5 6 7\n"
                                 "t corner 1/1/0 3 0.5\n", ["-d", "4"], "no polygon"),
    "fractional even, near a tag": ("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 3 0 0\nv 4 0 1\nv 5 0 0\nv 6 1 0\nv 7 0 0\nv 8 1 0\n"
                               "v 9 0 0\nv 10 1 0\nv 11 0 0\nv 12 1 0\nv 13 0 0\nl 1 2 3 4 5 6 7 8 9 10 11 12 13 14\n"
                               "t corner 1/1/0 3 0.5\nt corner 1/1/0 9 2\n", ["-d", "4"], "too close to another tag"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_one_line_exit_2_no_file(tmp_path, run_cli, capsys, case):
    """Two cases through a fresh interpreter, the others through ``export.cli.main`` in this
    one (the same code path, without 5 s of OpenCASCADE start-up each on a loaded machine)."""
    from export.cli import main

    suffix = "step" if len(case) % 2 else "obj"  # both writers, without doubling the runs
    text, extra, needle = BAD[case]
    src = tmp_path / "bad.obj"
    src.write_text(text)
    out = tmp_path / f"out.{suffix}"
    if case in ("one vertex", "NaN sharpness"):
        r = run_cli("curve", src, "-o", out, *extra)
        code, err = r.returncode, r.stderr
    else:
        code = main(["curve", str(src), "-o", str(out), *extra])
        err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("nupatch: error: ")
    assert needle in lines[0]
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [src]
