"""Subdivision curves to files and CAD objects (``nupatch curve``, docs/cli.md).

- ``.step .stp .iges .igs``: the exact limit (``Curve.limit()``) as one OpenCASCADE
  ``Geom_BSplineCurve`` of degree d (clamped; knots of multiplicity d at sharp vertices) in an
  edge; STEP AP214 in millimetres through ``export.step.write_step``, IGES through
  IGESControl_Writer.
- ``.dxf``: one non-rational SPLINE entity (ezdxf) per smooth run between sharp vertices,
  each with n + d + 1 clamped knots.
- ``.obj``: the polygon after ``steps`` subdivision steps as an ``l`` polyline (with its
  remaining ``t corner`` tags); ``.svg``: that polygon as an SVG polyline (x, y; y up).

- surfaces with control vectors on a regular grid ([KSD] eq. (15),
  ``patching.curves.surface_vectors.tensor_limit``): the exact limit as one
  ``Geom_BSplineSurface`` face (``to_face``, ``write_surface_step``).  General Catmull-Clark
  meshes with control vectors have no such form (extraordinary vertices): ``nupatch
  subdivide`` writes their refined mesh.

Every writer goes through ``export.atomic.atomic_output`` (no partial file on failure).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from patching.curves.curve import BSplineCurve, Curve
from patching.errors import OutputError, UnsupportedError

from .atomic import atomic_output

__all__ = [
    "CURVE_FORMATS",
    "to_geom_curve",
    "to_edge",
    "to_build123d",
    "to_cadquery",
    "write_curve",
    "subdivide_with_vectors",
    "to_geom_surface",
    "to_face",
    "write_surface_step",
    "grid_surface_with_vectors",
]


def _xyz(poles: np.ndarray) -> np.ndarray:
    poles = np.asarray(poles, dtype=np.float64)
    if poles.shape[1] == 2:
        poles = np.c_[poles, np.zeros(len(poles))]
    return poles


def to_geom_curve(spline: BSplineCurve | Curve):
    """An OpenCASCADE ``Geom_BSplineCurve`` with the limit's poles, knots and degree."""
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt
    from export.brep import knot_arrays
    from export.ocp_compat import TColgp_Array1OfPnt

    if not isinstance(spline, BSplineCurve):  # a Curve or a ModifiedQuinticCurve
        spline = spline.limit()
    poles = _xyz(spline.poles)
    P = TColgp_Array1OfPnt(1, len(poles))
    for i, p in enumerate(poles, start=1):
        P.SetValue(i, gp_Pnt(*map(float, p)))
    K, M = knot_arrays(*np.unique(spline.knots, return_counts=True))
    return Geom_BSplineCurve(P, K, M, int(spline.degree))


def to_edge(spline: BSplineCurve | Curve):
    """A ``TopoDS_Edge`` on the limit B-spline (valid: ``BRepCheck_Analyzer``)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge

    maker = BRepBuilderAPI_MakeEdge(to_geom_curve(spline))
    if not maker.IsDone():
        raise UnsupportedError("OpenCASCADE cannot make an edge of this curve (zero length?)")
    return maker.Edge()


def to_build123d(curve: Curve | BSplineCurve):
    """A ``build123d.Edge`` on the exact limit (a sweep path or a loft section)."""
    import build123d

    return build123d.Edge(to_edge(curve))


def to_cadquery(curve: Curve | BSplineCurve):
    """A ``cadquery.Wire`` of the one edge on the exact limit (``Workplane.sweep(path)``)."""
    import cadquery

    return cadquery.Wire.assembleEdges([cadquery.Edge(to_edge(curve))])


def _write_step(curve: Curve, tmp: Path, final: Path, steps: int) -> None:
    from .step import write_step_file

    write_step_file(to_edge(curve), tmp, curve.name, final.name)


def _write_iges(curve: Curve, tmp: Path, final: Path, steps: int) -> None:
    from OCP.IGESControl import IGESControl_Controller, IGESControl_Writer

    IGESControl_Controller.Init_s()
    writer = IGESControl_Writer("MM", 0)
    if not writer.AddShape(to_edge(curve)):
        raise OutputError("IGESControl_Writer.AddShape failed", final.name)
    writer.ComputeModel()
    if not writer.Write(str(tmp)):
        raise OutputError("IGESControl_Writer.Write failed", final.name)


def _write_dxf(curve: Curve, tmp: Path, final: Path, steps: int) -> None:
    try:
        import ezdxf
    except ImportError:  # a dependency of build123d, so normally present
        raise UnsupportedError("DXF output needs ezdxf (pip install 'ezdxf>=1.1,<2')", final.name) from None

    doc = ezdxf.new("R2010")
    doc.units = ezdxf.units.MM
    msp = doc.modelspace()
    for piece in curve.limit().split_at_sharp():
        spline = msp.add_spline(dxfattribs={"layer": curve.name or "curve"})
        spline.dxf.degree = piece.degree
        spline.control_points = _xyz(piece.poles).tolist()
        spline.knots = [float(k) for k in piece.knots]
    doc.saveas(tmp)


def _refined(curve: Curve, steps: int) -> Curve:
    return curve.refine(steps)


def _write_obj(curve: Curve, tmp: Path, final: Path, steps: int) -> None:
    c = _refined(curve, steps)
    lines = [f"# {curve.name}: degree {curve.degree} subdivision polygon after {steps} steps (nupatch curve)"]
    lines += [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in _xyz(c.points)]
    idx = list(range(1, len(c.points) + 1)) + ([1] if c.closed else [])
    lines.append("l " + " ".join(map(str, idx)))
    for v, s in enumerate(c.sharpness):
        if s > 0:
            lines.append(f"t corner 1/1/0 {v} {'inf' if math.isinf(s) else repr(float(s))}")
    tmp.write_text("\n".join(lines) + "\n")


def _write_svg(curve: Curve, tmp: Path, final: Path, steps: int) -> None:
    c = _refined(curve, steps)
    P = _xyz(c.points)[:, :2]
    lo, hi = P.min(axis=0), P.max(axis=0)
    size = float(max(hi - lo)) or 1.0
    pad = 0.05 * size
    pts = " ".join(f"{x:.9g},{-y:.9g}" for x, y in P)
    tag = "polygon" if c.closed else "polyline"
    w, h = hi - lo + 2 * pad
    tmp.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{lo[0] - pad:.9g} {-hi[1] - pad:.9g} {w:.9g} {h:.9g}">\n'
        f'  <{tag} points="{pts}" fill="none" stroke="black" stroke-width="{size / 500:.6g}"/>\n'
        "</svg>\n"
    )


CURVE_FORMATS = {
    ".step": _write_step,
    ".stp": _write_step,
    ".iges": _write_iges,
    ".igs": _write_iges,
    ".dxf": _write_dxf,
    ".obj": _write_obj,
    ".svg": _write_svg,
}


def write_curve(curve: Curve, path: str | os.PathLike, steps: int = 4) -> Path:
    """Write ``curve`` to ``path`` by its suffix (``CURVE_FORMATS``), atomically.

    ``steps``: subdivision steps of the ``.obj`` / ``.svg`` polygon (ignored by the exact
    formats).  The geometry is computed before the file is opened, so bad input leaves none.
    """
    path = Path(path)
    writer = CURVE_FORMATS.get(path.suffix.lower())
    if writer is None:
        raise OutputError(f"unknown curve format '{path.suffix}' (one of {', '.join(sorted(CURVE_FORMATS))})", str(path))
    if path.suffix.lower() in (".step", ".stp", ".iges", ".igs", ".dxf"):
        curve.limit()  # raise on bad input before any file exists
    with atomic_output(path) as tmp:
        writer(curve, tmp, path, steps)
    return path


def subdivide_with_vectors(mesh, mesh_path: str | os.PathLike, steps: int, rules: str, comment: str) -> str | None:
    """``nupatch subdivide`` of a quad mesh with ``t controlvector`` tags ([KSD] sec. 5,
    ``patching.curves.surface_vectors``): the refined mesh's OBJ text with the surviving
    vectors as tags, or None when the file has no such tag (the plain route applies)."""
    from patching.curves.surface_vectors import format_vector_tags, parse_vector_tags, refine
    from patching.mesh import format_obj
    from patching.subdivision.catmark import rules_tag
    from patching.topology.tables import Topology

    path = Path(mesh_path)
    if str(mesh_path) == "-" or path.suffix.lower() != ".obj":
        return None
    vectors, values = parse_vector_tags(path.read_text(encoding="utf-8-sig", errors="replace"), path.name)
    if not vectors:
        return None
    if not np.all(Topology(mesh).edge_interval == 1.0):
        raise UnsupportedError("control vectors need uniform knot intervals ([KSD] sec. 5 is uniform)", path.name)
    from patching.subdivision.catmark import MAX_SUBDIVIDE_FACES

    faces = int(mesh.face_sizes.sum()) * 4 ** (steps - 1) if steps else mesh.n_faces
    if faces > MAX_SUBDIVIDE_FACES:
        raise UnsupportedError(f"{steps} steps of {mesh.n_faces} faces make {faces:.3g} faces, more than "
                               f"{MAX_SUBDIVIDE_FACES:,}: take fewer steps", path.name)
    refined, kept, kept_values = refine(mesh, vectors, values, steps, rules=rules)
    return format_obj(refined, comment) + format_vector_tags(kept, kept_values) + rules_tag(rules) + "\n"


def to_geom_surface(surface, periodic: tuple[bool, bool] = (False, False)):
    """An OpenCASCADE ``Geom_BSplineSurface`` with the poles, knots and degrees of a
    ``patching.curves.surface_vectors.BSplineSurface`` (non-rational, clamped).

    ``periodic`` (a closed grid direction): the clamped surface is closed there and C^(d-1)
    across the seam, so OCC's ``SetUPeriodic`` (a periodic C0 seam of multiplicity d) and
    ``RemoveUKnot`` down to multiplicity 1 give the same surface as a periodic B-spline; the
    removal is checked by OCC to 1e-10 of the size and refused (OutputError) if it fails."""
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    from export.brep import knot_arrays
    from export.ocp_compat import TColgp_Array2OfPnt

    poles = np.asarray(surface.poles, dtype=np.float64)
    if poles.shape[2] == 2:
        poles = np.concatenate([poles, np.zeros(poles.shape[:2] + (1,))], axis=2)
    nu, nv, _ = poles.shape
    P = TColgp_Array2OfPnt(1, nu, 1, nv)
    for a in range(nu):
        for b in range(nv):
            P.SetValue(a + 1, b + 1, gp_Pnt(*map(float, poles[a, b])))
    ku, mu = knot_arrays(*np.unique(surface.knots_u, return_counts=True))
    kv, mv = knot_arrays(*np.unique(surface.knots_v, return_counts=True))
    du, dv = surface.degrees
    g = Geom_BSplineSurface(P, ku, kv, mu, mv, int(du), int(dv), False, False)
    tol = 1e-10 * max(1.0, float(np.abs(poles).max()))
    if periodic[0]:
        g.SetUPeriodic()
        if not g.RemoveUKnot(1, 1, tol):
            raise OutputError("the closed u direction does not join smoothly at its seam (knot removal failed)")
    if periodic[1]:
        g.SetVPeriodic()
        if not g.RemoveVKnot(1, 1, tol):
            raise OutputError("the closed v direction does not join smoothly at its seam (knot removal failed)")
    return g


def to_face(surface, periodic: tuple[bool, bool] = (False, False)):
    """A ``TopoDS_Face`` on the whole B-spline surface (valid: ``BRepCheck_Analyzer``);
    ``periodic`` as in ``to_geom_surface`` (a torus grid: a closed face with seam edges)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace

    maker = BRepBuilderAPI_MakeFace(to_geom_surface(surface, periodic), 1e-7)
    if not maker.IsDone():
        raise UnsupportedError("OpenCASCADE cannot make a face of this surface")
    return maker.Face()


def write_surface_step(surface, path: str | os.PathLike, name: str = "surface",
                       periodic: tuple[bool, bool] = (False, False)) -> Path:
    """The exact B-spline surface as one STEP face (AP214, mm), atomically."""
    from .step import write_step

    return write_step(to_face(surface, periodic), path, name)


def grid_surface_with_vectors(mesh, text: str, source: str):
    """``nupatch build`` of a regular quad grid with ``t controlvector`` tags: the exact
    surface of [KSD] eq. (15) (``surface_vectors.tensor_limit``, bicubic, Catmull-Clark's
    degree) and whether each direction is closed: ``(BSplineSurface, closed)``, or None when
    ``text`` has no such tag.

    The mesh's boundary rule decides the open directions' ends: interpolateboundary 1 (the
    default: boundary creases and corners) clamps them (on the grid this is Catmull-Clark's
    surface, so the vectors add to what ``nupatch build`` writes without them); 0 (boundary
    faces give no surface) leaves free ends, the full spans only.  Refused in one line: a mesh
    that is no regular grid (the first extraordinary vertex named), interpolateboundary 2 (its
    smoothed corners are no tensor product), crease, corner or hole tags, non-uniform intervals,
    and a vector closer than ``curve.VECTOR_CLEARANCE[3]`` lines to a clamped boundary.
    """
    from patching.curves.curve import VECTOR_CLEARANCE
    from patching.curves.surface_vectors import grid_of, grid_vectors, parse_vector_tags, tensor_limit
    from patching.topology.tables import Topology

    vectors, values = parse_vector_tags(text, source)
    if not vectors:
        return None
    if mesh.creases or mesh.corners or len(mesh.holes):
        what = "crease" if mesh.creases else ("corner" if mesh.corners else "hole")
        raise UnsupportedError(f"control vectors with {what} tags: the exact grid surface takes only the grid, "
                               "its boundary rule and the vectors ('nupatch subdivide' refines such meshes)", source)
    if not np.all(Topology(mesh).edge_interval == 1.0):
        raise UnsupportedError("control vectors need uniform knot intervals ([KSD] sec. 5 is uniform)", source)
    if mesh.interpolate_boundary == 2:
        raise UnsupportedError("control vectors with interpolateboundary 2: its smoothed corners are no tensor "
                               "product; use 1 (clamped) or 0 (free ends)", source)
    ids, closed = grid_of(mesh)
    tvecs = grid_vectors(ids, vectors)
    sharp = mesh.interpolate_boundary == 1
    ends = (sharp and not closed[0], sharp and not closed[1])
    gap = VECTOR_CLEARANCE[3]
    for (kind, i, j, _), vec in zip(tvecs, vectors):
        for along, k, size, clamped in (("u", i, ids.shape[0], ends[0]), ("v", j, ids.shape[1], ends[1])):
            crosses = kind == "X" or (kind == "V" and along == "u") or (kind == "U" and along == "v")
            if clamped and crosses and min(k, size - 1 - k) < gap:
                raise UnsupportedError(f"control vector {min(k, size - 1 - k)} grid lines from the clamped boundary: "
                                       f"bicubic needs {gap}", f"vertex {vec.vertex}")
    P = mesh.vertices[ids]
    return tensor_limit(P, (3, 3), closed, tvecs, values, ends=ends), closed

