"""Bézier patches to an OpenCASCADE B-rep with shared topology (docs/surface.md).

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
  whenever the two patches agree on the shared boundary row: SameParameter holds exactly;
- split sides (T-junctions, ``PatchTopology.pieces``): a side made of pieces [u0, u1] has one
  edge per piece, listed in order in the face's wire.  The edge's 3D curve is the row of the
  side it covers whole (the fine patch's), and its pcurve on the split (coarse) side the
  degree-1 segment from C_k + u0 (C_{k+1} - C_k) to C_k + u1 (C_{k+1} - C_k), w in [0, 1]
  (swapped when the piece is reversed): the coarse patch on that segment is the de Casteljau
  piece of its side row, which is the fine row when the patches agree, so SameParameter
  still holds exactly.  T-vertices are the fine patches' corners.

Side rows of a (d+1, d+1) net, in the side's direction (the module docstring of
``patching.surface`` draws the square)::

    side 0: net[0..d, 0]      (s: 0->1, t = 0)
    side 1: net[d, 0..d]      (s = 1,   t: 0->1)
    side 2: net[d..0, d]      (s: 1->0, t = 1)
    side 3: net[0, d..0]      (s = 0,   t: 1->0)
"""

from __future__ import annotations

import warnings

import numpy as np
from .ocp_compat import TColgp_Array1OfPnt, TColgp_Array1OfPnt2d, TColgp_Array2OfPnt, TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.BRep import BRep_Builder
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.Geom import Geom_BezierCurve, Geom_BezierSurface
from OCP.Geom2d import Geom2d_BezierCurve, Geom2d_Line
from OCP.gp import gp_Dir2d, gp_Pnt, gp_Pnt2d
from OCP.GProp import GProp_GProps
from OCP.Precision import Precision
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

from export.tolerances import RELATIVE_TOLERANCE
from patching.errors import MeshError
from patching.mesh import NupatchWarning
from patching.surface import CORNER_PARAMETERS, BezierSurface

__all__ = [
    "BrepError", "bezier_curve", "bezier_surface", "knot_arrays", "line_2d", "pcurve", "side_row", "to_shape", "shape_tolerance", "assemble", "bound_face", "bound_face_pieces", "make_vertices", "make_edges", "make_edge", "edge_curves", "side_point", "piece_lists", "patch_wire", "checked_patches",
    "no_volume_components", "warn_no_volume", "refuse_round_off", "shape_face_rows",
]

class BrepError(RuntimeError):
    """OpenCASCADE rejected a B-rep built from a consistent surface: a bug, not bad input."""


def side_row(net: np.ndarray, side: int) -> np.ndarray:
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


def bezier_surface(net: np.ndarray) -> Geom_BezierSurface:
    n = net.shape[0]
    poles = TColgp_Array2OfPnt(1, n, 1, n)
    # tolist: Python floats in one call (the same values as float() of each numpy scalar)
    for i, row in enumerate(np.asarray(net, dtype=np.float64).tolist(), 1):
        for j, (x, y, z) in enumerate(row, 1):
            poles.SetValue(i, j, gp_Pnt(x, y, z))
    return Geom_BezierSurface(poles)


def bezier_curve(row: np.ndarray) -> Geom_BezierCurve:
    poles = TColgp_Array1OfPnt(1, len(row))
    for i, (x, y, z) in enumerate(np.asarray(row, dtype=np.float64).tolist(), 1):
        poles.SetValue(i, gp_Pnt(x, y, z))
    return Geom_BezierCurve(poles)


def knot_arrays(knots, mults) -> tuple[TColStd_Array1OfReal, TColStd_Array1OfInteger]:
    """OpenCASCADE's arrays of a B-spline's distinct knots and their multiplicities."""
    k = TColStd_Array1OfReal(1, len(knots))
    m = TColStd_Array1OfInteger(1, len(knots))
    for i, (x, n) in enumerate(zip(np.asarray(knots, dtype=np.float64).tolist(), np.asarray(mults).tolist()), 1):
        k.SetValue(i, x)
        m.SetValue(i, int(n))
    return k, m


def pcurve(side: int, reversed_: bool) -> Geom2d_Line:
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
    ids = np.asarray(topo.corner_vertex)
    if ids.size and (ids.min() < 0 or ids.max() >= topo.n_vertices):
        raise BrepError(f"PatchTopology.corner_vertex has ids outside 0..{topo.n_vertices - 1}")
    if topo.side_indptr is None:
        ids = np.asarray(topo.side_edge)
        if ids.size and (ids.min() < 0 or ids.max() >= topo.n_edges):
            raise BrepError(f"PatchTopology.side_edge has ids outside 0..{topo.n_edges - 1}")
    else:
        _check_pieces(topo, p)
    # Every piece must join its edge's two vertices in the edge's direction.
    pieces = topo.pieces
    start = np.where(pieces.reversed, pieces.vertex[:, 1], pieces.vertex[:, 0])
    end = np.where(pieces.reversed, pieces.vertex[:, 0], pieces.vertex[:, 1])
    ends = np.full((topo.n_edges, 2), -1, dtype=np.int64)
    ids, first = np.unique(pieces.edge, return_index=True)
    ends[ids] = np.stack([start[first], end[first]], axis=1)  # as its first piece
    bad = np.flatnonzero((ends[pieces.edge, 0] != start) | (ends[pieces.edge, 1] != end))
    if len(bad):
        i = int(bad[0])
        row, side = divmod(int(pieces.side[i]), 4)
        raise BrepError(
            f"patch {row} side {side} runs between vertices {start[i]}, {end[i]} "
            f"but its edge {pieces.edge[i]} between {ends[pieces.edge[i]].tolist()}"
        )
    _check_nets(surface)
    return patches


def _check_nets(surface: BezierSurface) -> None:
    """Every patch's net is (d + 1, d + 1, 3) with d >= 1 and finite, checked a group at a time
    (the pawn's 93k patches: 0.02 s, one patch at a time 0.2 s); a group that is not one such
    array is checked patch by patch, for the same message."""
    row = 0
    for g in surface.groups:
        d, nets = g.degree, g.coefficients
        if isinstance(nets, np.ndarray) and nets.ndim == 4 and d >= 1 and nets.shape[1:] == (d + 1, d + 1, 3):
            bad = np.flatnonzero(~np.isfinite(nets).all(axis=(1, 2, 3)))
            if bad.size:
                k = int(bad[0])
                raise BrepError(f"patch {row + k} (face {int(g.faces[k])}): non-finite coefficients")
        else:
            for k, (face, net) in enumerate(zip(g.faces, nets)):
                net = np.asarray(net)
                if d < 1 or net.shape != (d + 1, d + 1, 3):
                    raise BrepError(f"patch {row + k} (face {int(face)}): net shape {net.shape}, degree {d}")
                if not np.all(np.isfinite(net)):
                    raise BrepError(f"patch {row + k} (face {int(face)}): non-finite coefficients")
        row += len(g.faces)


def _check_pieces(topo, p: int) -> None:
    """The split-side arrays against ``PatchTopology``'s contract: CSR shape, pieces tiling
    [0, 1] from corner k to corner k+1 through shared break vertices, side_edge in step."""
    indptr = np.asarray(topo.side_indptr)
    if indptr.shape != (4 * p + 1,) or indptr[0] != 0 or np.any(np.diff(indptr) < 1):
        raise BrepError(f"PatchTopology.side_indptr must be ({4 * p + 1},), from 0, at least one piece a side")
    pieces = topo.pieces
    m = int(indptr[-1])
    for name, shape in (("edge", (m,)), ("reversed", (m,)), ("range", (m, 2)), ("vertex", (m, 2))):
        if getattr(pieces, name).shape != shape:
            raise BrepError(f"PatchTopology.piece_{name} has shape {getattr(pieces, name).shape}, expected {shape}")
    for name, ids, n in (("piece_edge", pieces.edge, topo.n_edges), ("piece_vertex", pieces.vertex, topo.n_vertices)):
        if ids.size and (ids.min() < 0 or ids.max() >= n):
            raise BrepError(f"PatchTopology.{name} has ids outside 0..{n - 1}")
    first, last = indptr[:-1], indptr[1:] - 1
    corner = np.asarray(topo.corner_vertex, dtype=np.int64)
    u, v = pieces.range, pieces.vertex
    inner = np.ones(m, dtype=bool)
    inner[first] = False  # pieces that follow another one on their side
    problems = [
        (~((u[:, 0] < u[:, 1]) & (u[:, 0] >= 0.0) & (u[:, 1] <= 1.0)), "an empty or reversed range"),
        (inner & (np.r_[0.0, u[:-1, 1]] != u[:, 0]), "a gap or overlap with the piece before it"),
        (inner & (np.r_[-1, v[:-1, 1]] != v[:, 0]), "a start vertex other than the end of the piece before it"),
    ]
    for bad, what in problems:
        if bad.any():
            row, side = divmod(int(pieces.side[np.flatnonzero(bad)[0]]), 4)
            raise BrepError(f"patch {row} side {side}: a piece with {what}")
    ends = (
        (u[first, 0] != 0.0) | (u[last, 1] != 1.0)
        | (v[first, 0] != corner.ravel()) | (v[last, 1] != np.roll(corner, -1, axis=1).ravel())
    )
    one = (first == last) & pieces.whole[first]
    side_edge = np.asarray(topo.side_edge).ravel()
    side_reversed = np.asarray(topo.side_reversed).ravel()
    mismatch = np.where(one, (side_edge != pieces.edge[first]) | (side_reversed != pieces.reversed[first]), side_edge != -1)
    for bad, what in ((ends, "pieces that do not run from corner to corner"), (mismatch, "side_edge out of step with its pieces")):
        if bad.any():
            row, side = divmod(int(np.flatnonzero(bad)[0]), 4)
            raise BrepError(f"patch {row} side {side}: {what}")


def to_shape(surface: BezierSurface, *, check: bool = True) -> TopoDS_Shape:
    """Build the B-rep of ``surface``: a solid when its topology is closed, else a shell.

    One face per patch on its Bézier surface, with vertices and edges shared through
    ``surface.topology`` (no sewing).  A closed shell is oriented so that the solid's volume
    (``BRepGProp``) is positive.  With ``check`` (the default) ``BRepCheck_Analyzer`` must
    accept the result, else ``BrepError``; ``check=False`` returns it unchecked, for tests
    that measure deliberately inconsistent surfaces.
    """
    patches = checked_patches(surface, check)
    topo = surface.topology
    tol = shape_tolerance(surface)
    builder = BRep_Builder()
    pieces = topo.pieces
    nets = [net for _row, _degree, _face, net in patches]

    vertices = make_vertices(builder, topo, nets, tol)
    # Edges: 3D curve from each edge's source piece (PatchTopology), between the shared vertices.
    edges = make_edges(builder, pieces, topo.n_edges, nets, vertices, tol)

    # Faces: surface, pcurves (two on one face for a seam edge), wire of the oriented pieces.
    faces: list[TopoDS_Face] = []
    lists = piece_lists(pieces)
    for row, net in enumerate(nets):
        f = TopoDS_Face()
        builder.MakeFace(f, bezier_surface(net), tol)
        bound_face_pieces(builder, f, patch_wire(lists, row), edges, tol)
        faces.append(f)

    label, closed = patch_components(topo)
    sizes = iter(component_sizes(surface, label, closed.size)[closed].tolist())
    flat: list[int] = []  # positions among the closed components of those with no volume
    seen = [0]

    def orient(solid) -> bool | None:
        volume, size = _volume(solid), next(sizes)
        seen[0] += 1
        if _encloses_nothing(volume, size):
            flat.append(seen[0] - 1)
            return None
        return volume < 0.0

    shape = assemble(builder, edges, faces, topo, orient)
    warn_no_volume(surface, label, closed, flat)
    if check:
        _require_valid(shape, faces, patches, surface)
    return shape


def piece_lists(pieces) -> tuple[list, ...]:
    """(indptr, edge, reversed, whole, range) of ``SidePieces`` as Python lists, for the
    per-face loops of ``patch_wire``."""
    return tuple(a.tolist() for a in (pieces.indptr, pieces.edge, pieces.reversed, pieces.whole, pieces.range))


def patch_wire(lists, row: int) -> list[tuple[int, bool, object]]:
    """The wire of patch ``row`` on its own Bézier face, as (edge id, reversed, pcurve) in
    order: side by side, piece by piece; a whole side's pcurve is ``pcurve``, a piece's the
    segment of its range (``side_point``)."""
    indptr, edge_of, reversed_, whole, ranges = lists
    wire = []
    for k in range(4):
        for i in range(indptr[4 * row + k], indptr[4 * row + k + 1]):
            if whole[i]:
                curve = pcurve(k, reversed_[i])
            else:
                u0, u1 = ranges[i][::-1] if reversed_[i] else ranges[i]
                curve = line_2d(side_point(k, u0), side_point(k, u1))
            wire.append((edge_of[i], reversed_[i], curve))
    return wire


def checked_patches(surface: BezierSurface, check: bool = True) -> list[tuple[int, int, int, np.ndarray]]:
    """[(row, degree, face, (d+1, d+1, 3) net)] of ``surface`` in row order, after the checks
    every B-rep builder (``to_shape``, ``export.pack``) makes first: the topology arrays
    against the patches (BrepError: a bug), and with ``check`` no patch side of no length
    (MeshError naming the face: bad input)."""
    patches = _check_input(surface)
    if check:
        _refuse_degenerate_sides(surface, patches, shape_tolerance(surface))
    return patches


def component_sizes(surface: BezierSurface, label: np.ndarray, n: int) -> np.ndarray:
    """(n,) size of each connected component of the patches (``patch_components``' labels):
    the largest extent of the bounding box of its coefficients, as ``surface.size`` is for the
    whole surface."""
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    rows = [np.asarray(g.coefficients).reshape(len(g.faces), -1, 3) for g in surface.groups if len(g.faces)]
    if rows:
        mins = np.concatenate([r.min(axis=1) for r in rows])
        maxs = np.concatenate([r.max(axis=1) for r in rows])
        np.minimum.at(lo, label, mins)
        np.maximum.at(hi, label, maxs)
    return np.where(np.isfinite(hi - lo), hi - lo, 0.0).max(axis=1)


def _encloses_nothing(volume: float, size: float) -> bool:
    """A closed component's volume is zero to within its own tolerance x its own size^2 (the
    tolerance a B-rep of that component alone would get, ``shape_tolerance``)."""
    tol = max(Precision.Confusion_s(), RELATIVE_TOLERANCE * size)
    return abs(float(volume)) <= tol * max(size, tol) ** 2


def no_volume_components(surface: BezierSurface, volumes) -> list[int]:
    """Positions, among the closed components (in ``patch_components`` order), of those whose
    volume (``volumes``, one per closed component) is zero on their own scale."""
    label, closed = patch_components(surface.topology)
    sizes = component_sizes(surface, label, closed.size)[closed]
    return [i for i, (v, s) in enumerate(zip(np.asarray(volumes, float).tolist(), sizes.tolist())) if _encloses_nothing(v, s)]


def warn_no_volume(surface: BezierSurface, label: np.ndarray, closed: np.ndarray, flat) -> None:
    """One NupatchWarning naming the closed components that enclose no volume (``flat``:
    positions among the closed components), which ``assemble`` wrote as shells: the control
    points of a closed piece lie in a surface of no thickness (a flat pillow), so that piece
    gives no solid, and the rest of the model is still written."""
    if not len(flat):
        return
    closed_ids = np.flatnonzero(closed)
    rows_face = np.concatenate([np.asarray(g.faces, dtype=np.int64) for g in surface.groups]) if surface.groups else np.zeros(0, np.int64)
    named = []
    for k in list(flat)[:3]:
        rows = np.flatnonzero(label == closed_ids[k])
        named.append(f"the piece of mesh face {int(rows_face[rows[0]])} ({rows.size} patches)")
    more = f" and {len(flat) - 3} more" if len(flat) > 3 else ""
    n = len(flat)
    warnings.warn(
        NupatchWarning(
            f"{n} closed piece{'s' if n > 1 else ''} of {surface.name} enclose{'' if n > 1 else 's'} no volume "
            f"({', '.join(named)}{more}): written as {'shells, not solids' if n > 1 else 'a shell, not a solid'}"
        ),
        stacklevel=3,
    )


#: Round-off of the coordinates, as a fraction of the tolerance, from which a B-rep that
#: OpenCASCADE rejects is put down to the coordinates: meshes moved away from the origin are
#: rejected from 0.35 to 0.9 (cube, bipyramid, grids, torus, l_bracket), valid below.
ROUND_OFF_FRACTION = 0.1


def refuse_round_off(surface: BezierSurface) -> None:
    """MeshError when the coordinates' round-off (machine epsilon times the largest
    coefficient) reaches ``ROUND_OFF_FRACTION`` of the tolerance (1e-7 x size): a small mesh
    far from the origin, whose points doubles cannot place within the tolerance.  Called when
    ``BRepCheck_Analyzer`` rejects a B-rep, before calling that a bug."""
    tol = shape_tolerance(surface)
    largest = max((float(np.abs(g.coefficients).max()) for g in surface.groups if len(g.faces)), default=0.0)
    round_off = float(np.finfo(np.float64).eps) * largest
    if round_off >= ROUND_OFF_FRACTION * tol:
        raise MeshError(
            f"coordinates up to {largest:.3g} are too far from the origin for a mesh of size {surface.size:.3g}: "
            f"their round-off ({round_off:.2g}) reaches the B-rep tolerance ({tol:.2g}); move the mesh nearer the origin",
            surface.name,
        )


def _refuse_degenerate_sides(surface: BezierSurface, patches, tol: float) -> None:
    """A patch side whose boundary curve has no length (all its poles within the tolerance)
    is degenerate geometry from the control points, or from a knot interval so small against
    its neighbours' that the patch is thinner than the tolerance (1e-9 beside 1: not a zero
    interval, which gives no patch): refused naming the mesh face (exit 2)."""
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
                "(its control points coincide, or its knot interval is tiny against its neighbours')",
                f"face {face}",
            )


def side_point(side: int, u: float) -> np.ndarray:
    """(s, t) of parameter u along ``side`` of the parameter square: C_k + u (C_{k+1} - C_k)."""
    a, b = CORNER_PARAMETERS[side], CORNER_PARAMETERS[(side + 1) % 4]
    return a + u * (b - a)


def line_2d(a, b) -> Geom2d_BezierCurve:
    """Degree-1 pcurve from a to b with parameter w in [0, 1]."""
    poles = TColgp_Array1OfPnt2d(1, 2)
    poles.SetValue(1, gp_Pnt2d(float(a[0]), float(a[1])))
    poles.SetValue(2, gp_Pnt2d(float(b[0]), float(b[1])))
    return Geom2d_BezierCurve(poles)


def _de_casteljau(row: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """The Bézier curve ``row`` (d+1, 3) split at u: poles of its pieces on [0, u] and [u, 1]
    (The NURBS Book, eq. 5.5 / A5.6's triangle)."""
    left, right = [row[0]], [row[-1]]
    level = np.asarray(row, dtype=np.float64)
    while len(level) > 1:
        level = (1.0 - u) * level[:-1] + u * level[1:]
        left.append(level[0])
        right.append(level[-1])
    return np.array(left), np.array(right[::-1])


def _sub_row(row: np.ndarray, u0: float, u1: float) -> np.ndarray:
    """Poles of the Bézier curve ``row`` restricted to [u0, u1], parameter rescaled to [0, 1]."""
    if u1 < 1.0:
        row = _de_casteljau(row, u1)[0]
    if u0 > 0.0:
        row = _de_casteljau(row, u0 / u1)[1]
    return row


def make_vertices(builder: BRep_Builder, topo, nets, tol: float, used=None) -> list[TopoDS_Vertex]:
    """One ``TopoDS_Vertex`` per vertex id: the corner coefficient of the first patch corner
    using it, then T-vertices that are no patch's corner at their point on the side they split
    (de Casteljau of the side row).  used: optional (n_vertices,) bool, the vertices wanted
    (None in the list for the others, e.g. inside a packed face)."""
    corner_vertex = np.asarray(topo.corner_vertex, dtype=np.int64)
    pieces = topo.pieces
    vertices: list[TopoDS_Vertex | None] = [None] * topo.n_vertices
    if used is not None:
        vertices = [None if u else False for u in np.asarray(used, dtype=bool).tolist()]  # False: not wanted

    def make_vertex(vid: int, point) -> None:
        v = TopoDS_Vertex()
        builder.MakeVertex(v, gp_Pnt(*(float(c) for c in point)), tol)
        vertices[vid] = v

    for row, net in enumerate(nets):
        d = net.shape[0] - 1
        corners = (net[0, 0], net[d, 0], net[d, d], net[0, d])
        for c in range(4):
            vid = corner_vertex[row, c]
            if vertices[vid] is None:
                make_vertex(vid, corners[c])
    for i in [i for i, v in enumerate(pieces.vertex[:, 0].tolist()) if vertices[v] is None]:
        row, k = divmod(int(pieces.side[i]), 4)
        make_vertex(int(pieces.vertex[i, 0]), _de_casteljau(side_row(nets[row], k), float(pieces.range[i, 0]))[0][-1])
    return [v if v is not False else None for v in vertices]


def edge_curves(pieces, n_edges: int, nets, used=None) -> dict[int, tuple[np.ndarray, int, int]]:
    """{edge id: (curve row (d+1, 3), start vertex, end vertex)} in order of first use: the
    3D curve and direction of each edge's source piece (its first whole-side piece, else its
    first piece, ``PatchTopology``).  used: optional (n_edges,) bool, the edges wanted."""
    m = pieces.edge.size
    order = np.arange(m, dtype=np.int64)
    first = np.full(n_edges, m, dtype=np.int64)
    np.minimum.at(first, pieces.edge, order)
    if np.any(first == m):
        raise BrepError("PatchTopology.n_edges counts edges that no patch side uses")
    source = np.full(n_edges, 2 * m, dtype=np.int64)
    np.minimum.at(source, pieces.edge, np.where(pieces.whole, order, m + order))
    source = np.where(source >= m, source - m, source)
    eids = np.argsort(first, kind="stable")
    if used is not None:
        eids = eids[np.asarray(used, dtype=bool)[eids]]
    src = source[eids]  # the source pieces of the wanted edges only, as Python lists
    side, whole, ranges, vertex, reversed_ = (
        np.asarray(a)[src].tolist() for a in (pieces.side, pieces.whole, pieces.range, pieces.vertex, pieces.reversed)
    )
    out = {}
    for i, eid in enumerate(eids.tolist()):
        row, k = divmod(side[i], 4)
        curve_row = side_row(nets[row], k)
        if not whole[i]:
            curve_row = _sub_row(curve_row, *ranges[i])
        v0, v1 = vertex[i]
        if reversed_[i]:  # the contract makes the source piece forward; follow it regardless
            curve_row, v0, v1 = curve_row[::-1], v1, v0
        out[eid] = (curve_row, v0, v1)
    return out


def make_edge(builder: BRep_Builder, curve, v0: TopoDS_Vertex, v1: TopoDS_Vertex, tol: float) -> TopoDS_Edge:
    """A ``TopoDS_Edge`` on the 3D curve ``curve`` from vertex v0 to v1."""
    e = TopoDS_Edge()
    builder.MakeEdge(e, curve, tol)
    builder.Add(e, v0.Oriented(TopAbs_FORWARD))
    builder.Add(e, v1.Oriented(TopAbs_REVERSED))
    return e


def make_edges(builder: BRep_Builder, pieces, n_edges: int, nets, vertices, tol: float) -> list[TopoDS_Edge]:
    """One ``TopoDS_Edge`` per edge id (``edge_curves``), a Bézier curve between the shared
    vertices."""
    edges: list[TopoDS_Edge | None] = [None] * n_edges
    for eid, (curve_row, v0, v1) in edge_curves(pieces, n_edges, nets).items():
        edges[eid] = make_edge(builder, bezier_curve(curve_row), vertices[v0], vertices[v1], tol)
    return edges


def bound_face(builder: BRep_Builder, face: TopoDS_Face, sides, edges, side_edge, side_reversed, tol: float) -> None:
    """Give ``face`` the pcurves of its sides, a list of (patch row, side, pcurve) in wire
    order (two pcurves on one edge that bounds the face twice: a seam), and its closed wire of
    shared edges oriented by ``side_reversed``."""
    pieces = [(int(side_edge[r, k]), bool(side_reversed[r, k]), c) for r, k, c in sides]
    bound_face_pieces(builder, face, pieces, edges, tol)


def bound_face_pieces(builder: BRep_Builder, face: TopoDS_Face, pieces, edges, tol: float) -> None:
    """``bound_face`` on a list of (edge id, reversed, pcurve) in wire order."""
    pcurves: dict[int, dict[bool, object]] = {}
    for eid, rev, c in pieces:
        pcurves.setdefault(eid, {})[rev] = c
    for eid, by_orientation in pcurves.items():
        if len(by_orientation) == 2:  # seam: the edge bounds this face on two sides
            builder.UpdateEdge(edges[eid], by_orientation[False], by_orientation[True], face, tol)
        else:
            (c,) = by_orientation.values()
            builder.UpdateEdge(edges[eid], c, face, tol)
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    for eid, rev, _ in pieces:
        builder.Add(wire, edges[eid].Oriented(TopAbs_REVERSED if rev else TopAbs_FORWARD))
    wire.Closed(True)
    builder.Add(face, wire)


def patch_components(topo) -> tuple[np.ndarray, np.ndarray]:
    """(label per patch, closed per component): patches joined through shared edges; a
    component is closed when each of its edges is used twice (``PatchTopology``)."""
    from scipy.sparse import coo_matrix
    from patching.util.graph import connected_components

    pieces = topo.pieces
    p = np.shape(topo.corner_vertex)[0]
    rows = pieces.side // 4
    graph = coo_matrix((np.ones(rows.size), (rows, p + pieces.edge)), shape=(p + topo.n_edges,) * 2)
    _, label = connected_components(graph, directed=False)
    _, label = np.unique(label[:p], return_inverse=True)
    open_row = np.zeros(p, dtype=bool)
    open_row[rows[topo.edge_use_count[pieces.edge] < 2]] = True
    closed = np.bincount(label, weights=open_row, minlength=label.max() + 1 if p else 0) == 0
    return label.ravel(), closed


def shape_face_rows(topo) -> np.ndarray:
    """(p,) the patch row of each face of ``to_shape``'s result, in ``TopExp.MapShapes``
    order: ``assemble`` adds the faces component by component, rows ascending within each, so
    one component keeps the row order and several interleave it."""
    return np.argsort(patch_components(topo)[0], kind="stable")


def assemble(builder: BRep_Builder, edges, faces, topo, inside_out, face_rows=None) -> TopoDS_Shape:
    """Finish shared-topology faces: edge ranges, then a shell per connected component of the
    patches, and for a closed component a solid, turned around when ``inside_out(solid)`` says
    its volume is negative (True), or left a shell when it says None (no volume).  One
    component gives that shell or solid, several a compound.
    face_rows: a patch row of each face (default: face i is patch i).

    Every curve representation is parametrised on [0, 1] by construction (SameRange,
    SameParameter hold exactly)."""
    for e in edges:
        if e is None:  # an edge inside a packed face: made by no one
            continue
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
        turn = inside_out(solid)
        if turn is None:  # closed, but no volume: a shell (the caller warns)
            parts.append(shell)
            continue
        if turn:
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


def _require_valid(shape: TopoDS_Shape, faces: list[TopoDS_Face], patches, surface: BezierSurface) -> None:
    if BRepCheck_Analyzer(shape).IsValid():
        return
    refuse_round_off(surface)
    bad = []
    for f, (row, _degree, face, _net) in zip(faces, patches):
        if not BRepCheck_Analyzer(f).IsValid():
            bad.append(f"patch {row} (face {face})")
            if len(bad) == 5:
                break
    where = ", ".join(bad) if bad else "faces are valid alone; the shell or solid is not"
    raise BrepError(f"BRepCheck_Analyzer rejects the B-rep: {where}")
