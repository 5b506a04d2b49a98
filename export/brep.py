"""Bézier patches to an OpenCASCADE B-rep with shared topology (DESIGN 3).

Every patch becomes one face on a ``Geom_BezierSurface``; every ``PatchTopology`` vertex and
edge id becomes exactly one ``TopoDS_Vertex`` / ``TopoDS_Edge`` that all faces using it share,
so the result is watertight by construction and needs no sewing.

Conventions (see ``patching.surface`` for the patch point ordering):

- pole (i+1, j+1) of the face surface is ``net[i, j]``, U = s, V = t;
- an edge's 3D curve is the ``Geom_BezierCurve`` on the boundary row of its *first* side
  (table ``_SIDE_ROW`` below), parameter w in [0, 1] running in the edge's own direction;
- the pcurve of side k on its face is the straight line on the parameter square from
  corner k to corner k+1 (``CORNER_PARAMETERS``), or back when ``side_reversed``,
  parametrised by the same w, so pcurve(w) on the surface equals the 3D curve at w
  whenever the two patches agree on the shared boundary row: SameParameter holds exactly.

Side rows of a (d+1, d+1) net, in the side's direction (the module docstring of
``patching.surface`` draws the square)::

    side 0: net[0..d, 0]      (s: 0->1, t = 0)
    side 1: net[d, 0..d]      (s = 1,   t: 0->1)
    side 2: net[d..0, d]      (s: 1->0, t = 1)
    side 3: net[0, d..0]      (s = 0,   t: 1->0)
"""

from __future__ import annotations

import numpy as np
from OCP.BRep import BRep_Builder
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.Geom import Geom_BezierCurve, Geom_BezierSurface
from OCP.Geom2d import Geom2d_Line
from OCP.gp import gp_Dir2d, gp_Pnt, gp_Pnt2d
from OCP.GProp import GProp_GProps
from OCP.Precision import Precision
from OCP.TColgp import TColgp_Array1OfPnt, TColgp_Array2OfPnt
from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
from OCP.TopoDS import (
    TopoDS_Compound,
    TopoDS_Edge,
    TopoDS_Face,
    TopoDS_Shape,
    TopoDS_Shell,
    TopoDS_Solid,
    TopoDS_Vertex,
    TopoDS_Wire,
)

from patching.errors import MeshError
from patching.surface import CORNER_PARAMETERS, BezierSurface

__all__ = ["BrepError", "to_shape", "shape_tolerance", "assemble", "bound_face"]

#: Relative tolerance of vertices, edges and faces, times ``BezierSurface.size``.
RELATIVE_TOLERANCE = 1e-7


class BrepError(RuntimeError):
    """OpenCASCADE rejected a B-rep built from a consistent surface: a bug, not bad input."""


def _side_row(net: np.ndarray, side: int) -> np.ndarray:
    """(d+1, 3) boundary coefficients of ``side`` of a (d+1, d+1, 3) net, in the side's direction."""
    if side == 0:
        return net[:, 0]
    if side == 1:
        return net[-1, :]
    if side == 2:
        return net[::-1, -1]
    return net[0, ::-1]


def shape_tolerance(surface: BezierSurface) -> float:
    """Tolerance given to every vertex, edge and face: 1e-7 * size, at least Precision::Confusion."""
    return max(Precision.Confusion_s(), RELATIVE_TOLERANCE * float(surface.size))


def _bezier_surface(net: np.ndarray) -> Geom_BezierSurface:
    n = net.shape[0]
    poles = TColgp_Array2OfPnt(1, n, 1, n)
    for i in range(n):
        for j in range(n):
            x, y, z = net[i, j]
            poles.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(z)))
    return Geom_BezierSurface(poles)


def _bezier_curve(row: np.ndarray) -> Geom_BezierCurve:
    poles = TColgp_Array1OfPnt(1, len(row))
    for i, (x, y, z) in enumerate(row):
        poles.SetValue(i + 1, gp_Pnt(float(x), float(y), float(z)))
    return Geom_BezierCurve(poles)


def _pcurve(side: int, reversed_: bool) -> Geom2d_Line:
    """Line on the parameter square whose parameter w in [0, 1] is the edge's Bézier parameter."""
    a = CORNER_PARAMETERS[side]
    b = CORNER_PARAMETERS[(side + 1) % 4]
    if reversed_:
        a, b = b, a
    # Sides are unit length and axis-aligned, so the line's arc length is w.
    return Geom2d_Line(gp_Pnt2d(float(a[0]), float(a[1])), gp_Dir2d(float(b[0] - a[0]), float(b[1] - a[1])))


def _check_input(surface: BezierSurface) -> list[tuple[int, int, int, np.ndarray]]:
    topo = surface.topology
    patches = list(surface.patches())
    p = len(patches)
    if p == 0:
        raise BrepError("the surface has no patches")
    for name in ("corner_vertex", "side_edge", "side_reversed"):
        shape = np.shape(getattr(topo, name))
        if shape != (p, 4):
            raise BrepError(f"PatchTopology.{name} has shape {shape}, expected ({p}, 4)")
    for name, n in (("corner_vertex", topo.n_vertices), ("side_edge", topo.n_edges)):
        ids = np.asarray(getattr(topo, name))
        if ids.size and (ids.min() < 0 or ids.max() >= n):
            raise BrepError(f"PatchTopology.{name} has ids outside 0..{n - 1}")
    # Every side must join its edge's two vertices in the edge's direction.
    start = np.where(topo.side_reversed, np.roll(topo.corner_vertex, -1, axis=1), topo.corner_vertex)
    end = np.where(topo.side_reversed, topo.corner_vertex, np.roll(topo.corner_vertex, -1, axis=1))
    ends = np.full((topo.n_edges, 2), -1, dtype=np.int64)
    ids, first = np.unique(np.asarray(topo.side_edge).ravel(), return_index=True)
    ends[ids] = np.stack([start.ravel()[first], end.ravel()[first]], axis=1)  # as its first side
    bad = np.nonzero((ends[topo.side_edge, 0] != start) | (ends[topo.side_edge, 1] != end))
    if len(bad[0]):
        row, side = int(bad[0][0]), int(bad[1][0])
        raise BrepError(
            f"patch {row} side {side} runs between vertices {start[row, side]}, {end[row, side]} "
            f"but its edge {topo.side_edge[row, side]} between {ends[topo.side_edge[row, side]].tolist()}"
        )
    for row, degree, face, net in patches:
        if degree < 1 or net.shape != (degree + 1, degree + 1, 3):
            raise BrepError(f"patch {row} (face {face}): net shape {net.shape}, degree {degree}")
        if not np.all(np.isfinite(net)):
            raise BrepError(f"patch {row} (face {face}): non-finite coefficients")
    return patches


def to_shape(surface: BezierSurface, *, check: bool = True) -> TopoDS_Shape:
    """Build the B-rep of ``surface``: a solid when its topology is closed, else a shell.

    One face per patch on its Bézier surface, with vertices and edges shared through
    ``surface.topology`` (no sewing).  A closed shell is oriented so that the solid's volume
    (``BRepGProp``) is positive.  With ``check`` (the default) ``BRepCheck_Analyzer`` must
    accept the result, else ``BrepError``; ``check=False`` returns it unchecked, for tests
    that measure deliberately inconsistent surfaces.
    """
    patches = _check_input(surface)
    topo = surface.topology
    tol = shape_tolerance(surface)
    if check:
        _refuse_degenerate_sides(surface, patches, tol)
    builder = BRep_Builder()
    corner_vertex = np.asarray(topo.corner_vertex, dtype=np.int64)
    side_edge = np.asarray(topo.side_edge, dtype=np.int64)
    side_reversed = np.asarray(topo.side_reversed, dtype=bool)

    # Vertices: the corner coefficient of the first patch corner using each id.
    vertices: list[TopoDS_Vertex | None] = [None] * topo.n_vertices
    for row, _degree, _face, net in patches:
        d = net.shape[0] - 1
        corners = (net[0, 0], net[d, 0], net[d, d], net[0, d])
        for c in range(4):
            vid = corner_vertex[row, c]
            if vertices[vid] is None:
                v = TopoDS_Vertex()
                x, y, z = corners[c]
                builder.MakeVertex(v, gp_Pnt(float(x), float(y), float(z)), tol)
                vertices[vid] = v

    # Edges: 3D curve on the first side's boundary row, between the shared vertices.
    edges: list[TopoDS_Edge | None] = [None] * topo.n_edges
    for row, _degree, face, net in patches:
        for k in range(4):
            eid = side_edge[row, k]
            if edges[eid] is not None:
                continue
            # The contract makes the first side forward; follow side_reversed regardless.
            rev = bool(side_reversed[row, k])
            curve_row = _side_row(net, k)[::-1] if rev else _side_row(net, k)
            e = TopoDS_Edge()
            builder.MakeEdge(e, _bezier_curve(curve_row), tol)
            v0 = vertices[corner_vertex[row, (k + 1) % 4 if rev else k]]
            v1 = vertices[corner_vertex[row, k if rev else (k + 1) % 4]]
            builder.Add(e, v0.Oriented(TopAbs_FORWARD))
            builder.Add(e, v1.Oriented(TopAbs_REVERSED))
            edges[eid] = e
    if any(e is None for e in edges):
        raise BrepError("PatchTopology.n_edges counts edges that no patch side uses")

    # Faces: surface, pcurves (two on one face for a seam edge), wire of the 4 oriented edges.
    faces: list[TopoDS_Face] = []
    for row, _degree, _face, net in patches:
        f = TopoDS_Face()
        builder.MakeFace(f, _bezier_surface(net), tol)
        sides = [(row, k, _pcurve(k, bool(side_reversed[row, k]))) for k in range(4)]
        bound_face(builder, f, sides, edges, side_edge, side_reversed, tol)
        faces.append(f)

    volumes: list[float] = []
    shape = assemble(builder, edges, faces, topo, lambda solid: volumes.append(_volume(solid)) or volumes[-1] < 0.0)
    if check:
        if volumes and min(map(abs, volumes)) <= tol * max(surface.size, tol) ** 2:
            raise MeshError("degenerate geometry: the closed surface encloses no volume", surface.name)
        _require_valid(shape, faces, patches)
    return shape


def _refuse_degenerate_sides(surface: BezierSurface, patches, tol: float) -> None:
    """A patch side whose boundary curve has no length (all its poles within the tolerance)
    is degenerate geometry from the control points: refused naming the mesh face (exit 2)."""
    for group in surface.groups:
        nets = np.asarray(group.coefficients)
        sides = (nets[:, :, 0], nets[:, -1, :], nets[:, :, -1], nets[:, 0, :])  # (k, d+1, 3) each
        extent = np.stack([np.abs(c - c[:, :1]).max(axis=(1, 2)) for c in sides], axis=1)  # (k, 4)
        bad = np.argwhere(extent <= tol)
        if bad.size:
            k, side = (int(x) for x in bad[0])
            face = int(group.faces[k])
            raise MeshError(
                f"degenerate geometry: side {side} of the patch on face {face} has no length "
                "(its control points coincide)",
                f"face {face}",
            )


def bound_face(builder: BRep_Builder, face: TopoDS_Face, sides, edges, side_edge, side_reversed, tol: float) -> None:
    """Give ``face`` the pcurves of its sides, a list of (patch row, side, pcurve) in wire
    order (two pcurves on one edge that bounds the face twice: a seam), and its closed wire of
    shared edges oriented by ``side_reversed``."""
    pcurves: dict[int, dict[bool, object]] = {}
    for r, k, c in sides:
        pcurves.setdefault(int(side_edge[r, k]), {})[bool(side_reversed[r, k])] = c
    for eid, by_orientation in pcurves.items():
        if len(by_orientation) == 2:  # seam: the edge bounds this face on two sides
            builder.UpdateEdge(edges[eid], by_orientation[False], by_orientation[True], face, tol)
        else:
            (c,) = by_orientation.values()
            builder.UpdateEdge(edges[eid], c, face, tol)
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    for r, k, _ in sides:
        e = edges[int(side_edge[r, k])]
        builder.Add(wire, e.Oriented(TopAbs_REVERSED if side_reversed[r, k] else TopAbs_FORWARD))
    wire.Closed(True)
    builder.Add(face, wire)


def patch_components(topo) -> tuple[np.ndarray, np.ndarray]:
    """(label per patch, closed per component): patches joined through shared edges; a
    component is closed when each of its edges is used twice (``PatchTopology``)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    side_edge = np.asarray(topo.side_edge, dtype=np.int64)
    p = side_edge.shape[0]
    rows = np.repeat(np.arange(p), 4)
    graph = coo_matrix((np.ones(rows.size), (rows, p + side_edge.ravel())), shape=(p + topo.n_edges,) * 2)
    _, label = connected_components(graph, directed=False)
    _, label = np.unique(label[:p], return_inverse=True)
    open_edge = topo.edge_use_count[side_edge] < 2  # (p, 4)
    closed = np.bincount(label, weights=open_edge.any(axis=1), minlength=label.max() + 1 if p else 0) == 0
    return label.ravel(), closed


def assemble(builder: BRep_Builder, edges, faces, topo, inside_out, face_rows=None) -> TopoDS_Shape:
    """Finish shared-topology faces: edge ranges, then a shell per connected component of the
    patches, and for a closed component a solid, turned around when ``inside_out(solid)`` says
    its volume is negative.  One component gives that shell or solid, several a compound.
    face_rows: a patch row of each face (default: face i is patch i).

    Every curve representation is parametrised on [0, 1] by construction (SameRange,
    SameParameter hold exactly)."""
    for e in edges:
        builder.Range(e, 0.0, 1.0)
        builder.SameRange(e, True)
        builder.SameParameter(e, True)
    label, closed = patch_components(topo)
    face_label = label[np.arange(len(faces)) if face_rows is None else np.asarray(face_rows, dtype=np.int64)]
    parts = []
    for c in range(closed.size):
        shell = TopoDS_Shell()
        builder.MakeShell(shell)
        for i in np.flatnonzero(face_label == c).tolist():
            builder.Add(shell, faces[i])
        if not closed[c]:
            parts.append(shell)
            continue
        shell.Closed(True)
        solid = TopoDS_Solid()
        builder.MakeSolid(solid)
        builder.Add(solid, shell)
        if inside_out(solid):
            solid = TopoDS_Solid()
            builder.MakeSolid(solid)
            builder.Add(solid, shell.Reversed())
        parts.append(solid)
    if len(parts) == 1:
        return parts[0]
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    for part in parts:
        builder.Add(compound, part)
    return compound


def _volume(shape: TopoDS_Shape) -> float:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return props.Mass()


def _require_valid(shape: TopoDS_Shape, faces: list[TopoDS_Face], patches) -> None:
    if BRepCheck_Analyzer(shape).IsValid():
        return
    bad = []
    for f, (row, _degree, face, _net) in zip(faces, patches):
        if not BRepCheck_Analyzer(f).IsValid():
            bad.append(f"patch {row} (face {face})")
            if len(bad) == 5:
                break
    where = ", ".join(bad) if bad else "faces are valid alone; the shell or solid is not"
    raise BrepError(f"BRepCheck_Analyzer rejects the B-rep: {where}")
