"""Packed faces: rectangular blocks of bicubic patches as one multi-span B-spline face.

A regular region of the surface is, by construction (docs/knots.md, 3), one non-uniform bicubic
B-spline; ``to_shape`` nevertheless makes one Bézier face per patch.  Here blocks of bicubic
patches that lie in a rectangular grid become one ``Geom_BSplineSurface`` face each, re-using
the patches' coefficients only (no geometry rule is recomputed):

1. Blocks (``patching.evaluation.packing.find_blocks``): rectangular grids of bicubic patches
   joined through whole shared sides, grown greedily; a block never closes on itself (a full
   ring of a torus), so no packed face needs a seam, and never crosses a T-junction.
2. Surface.  The block's nets are the Bézier form of a bicubic B-spline (every interior knot of
   multiplicity 3), knots at the cumulative knot intervals of the block's columns and rows
   (``Topology.face_spans``, the intervals the patches were extracted with, in level-0 units
   on the adaptive path), in which the joins are C2; ``patching.evaluation.packing.reduce_block``
   removes each interior knot where the spans on both sides are one polynomial (all of them
   along a semi-sharp crease, where the subdivision is the uniform cubic B-spline rule along
   the crease at every level), else lowers it to multiplicity 1 (C2) or 2 (C1, beside a zero
   interval), to within ``KNOT_TOLERANCE``, and fits the poles by least squares.
3. Check.  The fitted B-spline's Bézier form (the exact linear map, ``bezier_matrix``) is compared with every
   patch of the block; a block that differs by more than ``EXACTNESS`` (relative to the
   surface size) keeps its knots at multiplicity >= 1, or failing that the Bézier form, and
   is not packed if even that is off (its patches stay Bézier faces): by the convex hull
   property the surface is never changed by more than that.
4. B-rep.  As ``export.brep.to_shape``, with shared vertices and edges: every patch side on a
   block's boundary keeps its own pieces (one whole edge, or the run of edges of a side split
   at T-junctions of the adaptive refinement), so neighbours, packed or not, share them, each
   with a degree-1 pcurve on the packed face between the piece's ends in the block's (u, v):
   the B-spline restricted to one span is the patch reparametrised linearly, so SameParameter
   holds exactly.  Edges inside a block disappear.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from .ocp_compat import TColgp_Array1OfPnt, TColgp_Array1OfPnt2d, TColgp_Array2OfPnt
from OCP.BRep import BRep_Builder
from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface
from OCP.Geom2d import Geom2d_BSplineCurve
from OCP.gp import gp_Pnt, gp_Pnt2d
from OCP.TopoDS import TopoDS_Face, TopoDS_Shape

from patching.bernstein import evaluate_nets
from patching.util.blas import one_blas_thread
from patching.util.vectors import cross3
from patching.surface import CORNER_PARAMETERS, BezierSurface

from patching.evaluation.packing import MAX_SIDE, Block, block_boundary, edge_chains, find_blocks, reduce_block, reduce_curve

from export.brep import (
    BrepError,
    bezier_surface,
    knot_arrays,
    line_2d,
    assemble,
    bound_face_pieces,
    bezier_curve,
    edge_curves,
    make_edge,
    make_vertices,
    checked_patches,
    patch_components,
    no_volume_components,
    warn_no_volume,
    refuse_round_off,
    shape_tolerance,
)

__all__ = ["Block", "MAX_SIDE", "PackReport", "find_blocks", "patch_spans", "to_packed_shape"]

#: Knot removal tolerance (model units, times the surface size): C2 joins of patches computed
#: in double precision agree to ~1e-15; 1e-13 leaves room for round-off only.
KNOT_TOLERANCE = 1e-13
#: Largest allowed difference between a packed face and its patches, times the surface size.
EXACTNESS = 1e-12


def _packed_surface(block: Block, nets: list[np.ndarray], size: float):
    """The B-spline of a block (steps 2 and 3): ``reduce_block``'s fewest-knot spline, checked
    against every patch to ``EXACTNESS``, as a ``Geom_BSplineSurface``; None if not even the
    Bézier form is the patches to that bound."""
    spline = reduce_block(block, nets, KNOT_TOLERANCE * size, EXACTNESS * max(size, 1e-300))
    u, v = block.knots
    if spline is None:
        return None, u, v, None
    nu, nv = spline.poles.shape[:2]
    poles = TColgp_Array2OfPnt(1, nu, 1, nv)
    set_pole, point = poles.SetValue, gp_Pnt()
    set_point = point.SetCoord
    for a, line in enumerate(spline.poles.tolist(), 1):
        for b, (x, y, z) in enumerate(line, 1):
            set_point(x, y, z)
            set_pole(a, b, point)  # SetValue copies
    (uk, um), (vk, vm) = (knot_arrays(k, m) for k, m in zip(spline.knots, spline.mults))
    return Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 3, False, False), u, v, spline.knots


@dataclass(frozen=True)
class PackReport:
    """faces of the packed B-rep; packed_faces of them B-spline blocks covering packed_patches
    of the surface's patches; blocks: the packed blocks, in face order (faces 0 ..
    packed_faces - 1 of the shape, in ``TopExp.MapShapes`` order), with their knots u, v."""

    faces: int
    packed_faces: int
    packed_patches: int
    patches: int
    blocks: tuple[tuple[Block, np.ndarray, np.ndarray], ...]


@one_blas_thread  # thousands of small products (the per-block check): no spinning BLAS threads
def to_packed_shape(surface: BezierSurface, spans: np.ndarray, *, check: bool = True) -> tuple[TopoDS_Shape, PackReport]:
    """The B-rep of ``surface`` with regular blocks packed (module docstring): a solid when
    closed, else a shell, checked by ``BRepCheck_Analyzer`` unless ``check`` is False.

    spans: (p, 2) knot intervals of every patch along its s and t (``patch_spans``).
    Split sides (T-junctions of adaptive refinement) are kept as in ``export.brep.to_shape``:
    a block's boundary side is tiled by its pieces, one shared edge each."""
    topo = surface.topology
    nets = [net for _, _, _, net in checked_patches(surface, check)]  # to_shape's checks: bad input is refused alike
    tol = shape_tolerance(surface)
    builder = BRep_Builder()
    pieces = topo.pieces

    faces_plan = []  # ("patch", row) or ("block", block, bspline, u, v)
    in_block = np.zeros(len(nets), dtype=bool)
    for block in find_blocks(surface, spans):
        bspline, u, v, knots = _packed_surface(block, nets, float(surface.size))
        if bspline is None:
            continue
        in_block[block.rows.ravel()] = True
        faces_plan.append(("block", block, bspline, u, v, knots))
    faces_plan += [("patch", row) for row in range(len(nets)) if not in_block[row]]

    # Sides on a face boundary: every side of a lone patch, the outer sides of a block.
    on_boundary = np.zeros(4 * len(nets), dtype=bool)
    on_boundary[4 * np.flatnonzero(~in_block)[:, None] + np.arange(4)] = True
    for plan in faces_plan:
        if plan[0] == "block":
            on_boundary[[4 * r + (k + t) % 4 for r, t, k in block_boundary(plan[1])]] = True
    used = np.zeros(topo.n_edges, dtype=bool)
    used[pieces.edge[on_boundary[pieces.side]]] = True
    curves = edge_curves(pieces, topo.n_edges, nets, used)
    used_vertices = np.zeros(topo.n_vertices, dtype=bool)
    used_vertices[[v for _, v0, v1 in curves.values() for v in (v0, v1)]] = True
    vertices = make_vertices(builder, topo, nets, tol, used_vertices)

    # Each face's wire: (edge, reversed, pcurve start, pcurve end), the pcurve a segment in
    # the face's (u, v) in the edge's own direction (``_wire_table``, all faces at once).
    surfaces = [bezier_surface(nets[plan[1]]) if plan[0] == "patch" else plan[2] for plan in faces_plan]
    face_of, edge_of, reversed_, start, end = _wire_table(faces_plan, pieces)
    bounds = np.searchsorted(face_of, np.arange(len(faces_plan) + 1)).tolist()
    entries = list(zip(edge_of.tolist(), reversed_.tolist(), start.tolist(), end.tolist()))
    wires = [entries[bounds[f] : bounds[f + 1]] for f in range(len(faces_plan))]

    # Runs of edges between the same two faces become one multi-span edge (edge_chains).
    chains = edge_chains([[(e, r) for e, r, _, _ in w] for w in wires], {e: c[1:] for e, c in curves.items()},
                         {e: len(c[0]) - 1 for e, c in curves.items()},
                         _turns(face_of, edge_of, reversed_, start, end, curves))
    # A chain's knots: the lengths of its segments in the (u, v) of a face it bounds (the
    # knot intervals there, in which the joins of same-level patches are C2), scaled to [0, 1].
    # The first face of the pair, for every edge of the chain alike: each edge's first entry.
    first_edges, first_at = np.unique(edge_of, return_index=True)
    lengths = np.abs(end[first_at, 0] - start[first_at, 0]) + np.abs(end[first_at, 1] - start[first_at, 1])
    length: dict[int, float] = dict(zip(first_edges.tolist(), lengths.tolist()))
    chain_of, chain_knots = {}, []
    edges = []
    for c, chain in enumerate(chains):
        at = np.concatenate([[0.0], np.cumsum([length[e] for e, _ in chain])])
        chain_knots.append(at / at[-1])
        rows = [curves[e][0][::-1] if back else curves[e][0] for e, back in chain]
        first, last = curves[chain[0][0]], curves[chain[-1][0]]
        v0 = first[2] if chain[0][1] else first[1]
        v1 = last[1] if chain[-1][1] else last[2]
        curve = bezier_curve(rows[0]) if len(rows) == 1 else _chain_curve(rows, chain_knots[c], KNOT_TOLERANCE * float(surface.size),
                                                                                     EXACTNESS * float(surface.size))
        edges.append(make_edge(builder, curve, vertices[v0], vertices[v1], tol))
        for k, (e, back) in enumerate(chain):
            chain_of[e] = (c, k, back)

    faces = []
    for surf, wire, plan in zip(surfaces, wires, faces_plan):
        f = TopoDS_Face()
        builder.MakeFace(f, surf, tol)
        face_knots = plan[5] if plan[0] == "block" else None
        bound_face_pieces(builder, f, _chained_wire(wire, chain_of, chains, chain_knots, face_knots), edges, tol)
        faces.append(f)

    # orientation as to_shape's test, without OCC's slow integration of multi-span faces
    face_rows = [plan[1] if plan[0] == "patch" else int(plan[1].rows.flat[0]) for plan in faces_plan]
    volumes = _component_volumes(surface)
    flat = no_volume_components(surface, volumes)
    order = iter([None if i in flat else v < 0.0 for i, v in enumerate(volumes.tolist())])
    shape = assemble(builder, edges, faces, topo, lambda solid: next(order), face_rows)
    warn_no_volume(surface, *patch_components(topo), flat)
    if check:
        from OCP.BRepCheck import BRepCheck_Analyzer

        if not BRepCheck_Analyzer(shape).IsValid():
            refuse_round_off(surface)
            raise BrepError("BRepCheck_Analyzer rejects the packed B-rep")
    blocks = tuple((p[1], p[3], p[4]) for p in faces_plan if p[0] == "block")
    return shape, PackReport(len(faces), len(blocks), int(in_block.sum()), len(nets), blocks)


def _wire_table(faces_plan, pieces) -> tuple[np.ndarray, ...]:
    """(face, edge, reversed, start (n, 2), end (n, 2)) of every wire entry of the faces, face
    by face in wire order: side k of a lone patch, or the boundary sides k of a block's cells
    (cell (i, j) at (u_i, v_j) with size (du_i, dv_j) in the block's (u, v)), each tiled by its
    pieces; a piece on [u0, u1] of its side (in the side's direction, the range swapped when the
    piece is reversed) runs from C_k + u0 (C_{k+1} - C_k) to C_k + u1 (C_{k+1} - C_k), scaled
    into the cell.  The patch's own side (k + t) mod 4 of a block's cell turned by t runs the
    same way as the block's side k (a turn keeps the orientation), so its pieces' u0, u1 map
    linearly onto it: the B-spline on that span is the patch, SameParameter holds."""
    cols = []  # per face: (row, own side, ou, ov, su, sv, k) of its cells, in wire order
    for f, plan in enumerate(faces_plan):
        if plan[0] == "patch":
            cols.append(np.array([[f, plan[1], k, 0.0, 0.0, 1.0, 1.0, k] for k in range(4)]))
        else:
            _, block, _, u, v, _ = plan
            cells = list(block_boundary(block, with_cell=True))
            ij = np.array([c[3] for c in cells], dtype=np.int64).reshape(-1, 2)
            rtk = np.array([c[:3] for c in cells], dtype=np.int64).reshape(-1, 3)
            cols.append(np.column_stack([np.full(len(cells), f), rtk[:, 0], (rtk[:, 2] + rtk[:, 1]) % 4,
                                         u[ij[:, 0]], v[ij[:, 1]], block.du[ij[:, 0]], block.dv[ij[:, 1]], rtk[:, 2]]))
    table = np.concatenate(cols) if cols else np.zeros((0, 8))
    face, side, k = table[:, 0].astype(np.int64), (4 * table[:, 1] + table[:, 2]).astype(np.int64), table[:, 7].astype(np.int64)
    origin, size = table[:, 3:5], table[:, 5:7]
    indptr = np.asarray(pieces.indptr, dtype=np.int64)
    count = indptr[side + 1] - indptr[side]
    cell = np.repeat(np.arange(len(side)), count)
    offset = np.cumsum(count) - count
    piece = indptr[side][cell] + np.arange(cell.size) - offset[cell]
    rev = np.asarray(pieces.reversed, dtype=bool)[piece]
    ranges = np.asarray(pieces.range, dtype=np.float64)[piece]
    ranges = np.where(rev[:, None], ranges[:, ::-1], ranges)
    c0, c1 = CORNER_PARAMETERS[k[cell]], CORNER_PARAMETERS[(k[cell] + 1) % 4]
    o, sz = origin[cell], size[cell]
    # side_point(k, w) = C_k + w (C_{k+1} - C_k), then into the cell: in this order of
    # operations (the pcurves are the ones the per-piece loop made, to the bit)
    start = o + sz * (c0 + ranges[:, :1] * (c1 - c0))
    end = o + sz * (c0 + ranges[:, 1:] * (c1 - c0))
    return face[cell], np.asarray(pieces.edge, dtype=np.int64)[piece], rev, start, end


def _turns(face, edge, rev, start, end, curves) -> set[int]:
    """Vertices where a face's wire turns: the segments of two consecutive wire entries (in
    the face's (u, v)) are not parallel there.  Arguments: ``_wire_table``'s."""
    if not face.size:
        return set()
    d = np.where(rev[:, None], start - end, end - start)
    bounds = np.searchsorted(face, np.arange(face.max() + 2))
    nxt = np.arange(face.size) + 1
    nxt[bounds[1:][np.diff(bounds) > 0] - 1] = bounds[:-1][np.diff(bounds) > 0]  # the last entry: the face's first
    d2 = d[nxt]
    norm = np.sqrt(np.einsum("ij,ij->i", d, d)) * np.sqrt(np.einsum("ij,ij->i", d2, d2))
    turn = np.abs(d[:, 0] * d2[:, 1] - d[:, 1] * d2[:, 0]) > 1e-9 * norm
    # the vertex the entry ends at
    return {curves[e][1] if r else curves[e][2] for e, r in zip(edge[turn].tolist(), rev[turn].tolist())}


def _chain_curve(rows: list[np.ndarray], knots_at: np.ndarray, tol: float, exact: float) -> Geom_BSplineCurve:
    """The Bézier rows (each (d+1, 3), end to start) as one B-spline curve on [0, 1], row k on
    [knots_at[k], knots_at[k+1]]: ``reduce_curve``'s fewest knots (removed where the joins are
    one polynomial, lowered where C2 or C1, to within ``tol``), checked against the rows to
    ``exact``, else the Bézier form (model units both)."""
    spline = reduce_curve(np.stack(rows), knots_at, tol, exact)
    poles = TColgp_Array1OfPnt(1, len(spline.poles))
    for i, (x, y, z) in enumerate(spline.poles.tolist(), 1):
        poles.SetValue(i, gp_Pnt(x, y, z))
    knots, mults = knot_arrays(spline.knots[0], spline.mults[0])
    return Geom_BSplineCurve(poles, knots, mults, spline.degree)


def _polyline_2d(points: list[np.ndarray], knots_at: np.ndarray, face_knots=None):
    """Degree-1 pcurve through ``points``, point k at ``knots_at[k]`` (the chain's parameter):
    its breakpoints removed where the polyline runs straight on at the same speed
    (``reduce_curve`` of degree 1, to 1e-14 of its extent in (u, v): round-off only), then put
    back where a segment crosses one of the face's knot lines (``face_knots``: its u and v
    knots, None for a Bézier face), so that each segment lies in one row of the face's spans.
    The curve is the same function of the parameter; the knot lines are for OpenCASCADE's
    mass properties, whose boundary integration takes the pcurve's segments as its intervals
    (one segment across many spans measured the volume of a packed torus 1.8e-11 off, at any
    tolerance, against 1e-16 with the knots).  A single segment is ``line_2d``."""
    points = np.asarray(points, dtype=np.float64)
    knots_at = np.asarray(knots_at, dtype=np.float64)
    tol = 1e-14 * max(float(np.abs(points - points[0]).max()), 1e-300)
    spline = reduce_curve(np.stack([points[:-1], points[1:]], axis=1), knots_at, tol, tol)
    poles, at = spline.poles, spline.knots[0]
    if face_knots is not None and len(poles) < len(points):
        new_poles, new_at = [poles[:1]], [at[:1]]
        for k in range(len(poles) - 1):
            a, b = poles[k], poles[k + 1]
            cut = [0.0, 1.0]
            for axis, lines in enumerate(face_knots):
                lo, hi = sorted((a[axis], b[axis]))
                inner = lines[(lines > lo + tol) & (lines < hi - tol)]
                cut += ((inner - a[axis]) / (b[axis] - a[axis])).tolist()
            w = np.unique(np.clip(cut, 0.0, 1.0))[1:]
            new_poles.append(a + w[:, None] * (b - a))
            new_at.append(at[k] + w * (at[k + 1] - at[k]))
        poles, at = np.concatenate(new_poles), np.concatenate(new_at)
        poles[-1], at[-1] = points[-1], knots_at[-1]
    if len(poles) == 2:
        return line_2d(*poles)
    n = len(poles)
    pcurve = TColgp_Array1OfPnt2d(1, n)
    for i, (x, y) in enumerate(poles.tolist(), 1):
        pcurve.SetValue(i, gp_Pnt2d(x, y))
    knots, mults = knot_arrays(at, np.r_[2, np.ones(n - 2, dtype=np.int64), 2])
    return Geom2d_BSplineCurve(pcurve, knots, mults, 1)


def _chained_wire(wire, chain_of: dict, chains, chain_knots, face_knots=None) -> list:
    """A face's wire of (edge, reversed, a, b) as (chain edge, reversed, pcurve): each run of
    one chain's edges (consecutive, perhaps around the wire's start) one entry, its pcurve the
    polyline of the run's segments in the chain's direction (``_polyline_2d``; face_knots:
    the face's u and v knots, None for a Bézier face)."""
    keys = [chain_of[e][0] for e, _, _, _ in wire]
    start = next((i for i in range(len(wire)) if keys[i] != keys[i - 1]), 0)
    wire, keys = wire[start:] + wire[:start], keys[start:] + keys[:start]
    out, i = [], 0
    while i < len(wire):
        c = keys[i]
        j = i
        while j < len(wire) and keys[j] == c:
            j += 1
        segment = {e: (a, b) for e, _, a, b in wire[i:j]}
        chain = chains[c]
        e0, rev0 = wire[i][0], wire[i][1]
        agree = rev0 == chain_of[e0][2]  # the face runs along the chain
        if len(chain) == 1:  # each use on its own (a seam uses its edge twice, both ways)
            out += [(c, rev, line_2d(a, b)) for _, rev, a, b in wire[i:j]]
        else:
            points = []
            for e, back in chain:
                a, b = segment[e]
                a, b = (b, a) if back else (a, b)
                points = points or [a]
                points.append(b)
            out.append((c, not agree, _polyline_2d(points, chain_knots[c], face_knots)))
        i = j
    return out


def _signed_volumes(surface: BezierSurface) -> np.ndarray:
    """Volume enclosed by each patch's cone to the origin, 1/3 of the integral of
    S . (S_s x S_t), in row order: summed over a closed component, its sign orients that
    solid.  For a degree-d patch the integrand has degree 3 d - 1 in s and in t, which
    Gauss-Legendre with ceil(3 d / 2) nodes integrates exactly (5 x 5 for bicubics)."""
    out = []
    for g in surface.groups:
        x, weights = np.polynomial.legendre.leggauss(-(-3 * int(g.degree) // 2))
        x, weights = (x + 1) / 2, weights / 2
        s, t = (a.ravel() for a in np.meshgrid(x, x, indexing="ij"))
        w = np.outer(weights, weights).ravel()
        p, ds, dt = evaluate_nets(g.coefficients, s, t, derivatives=True)
        out.append(np.einsum("m,kmc,kmc->k", w, p, cross3(ds, dt)) / 3)
    return np.concatenate(out) if out else np.zeros(0)


def _component_volumes(surface: BezierSurface) -> np.ndarray:
    """(c,) signed volume of each closed component of the patches, in component order (the
    order in which ``assemble`` asks whether a solid is inside out): its orientation test and
    the no-volume check without OCC's slow integration of multi-span faces."""
    label, closed = patch_components(surface.topology)
    volumes = np.bincount(label, weights=_signed_volumes(surface), minlength=closed.size)
    return volumes[closed]


def patch_spans(surface: BezierSurface, mesh) -> np.ndarray:
    """(p, 2) knot intervals of every patch along its s and t, from the mesh it was built from
    (``Topology.face_spans``: the intervals of the face's edges h0 and h1).  Wrong
    spans could not change the surface (a span of the triple-knot B-spline is its patch
    whatever its length), only keep knots from being removed."""
    from patching.operator import patched_mesh
    from patching.topology.tables import Topology

    if surface.groups and all(g.spans is not None for g in surface.groups):
        # The refinement gave them (the adaptive path: patches of several levels).
        return np.concatenate([np.asarray(g.spans, dtype=np.float64).reshape(-1, 2) for g in surface.groups])
    surface.topology.require_whole_sides("--pack")
    # build_operator patches the mesh after its global steps for semi-sharp tags and n-gons
    #: its faces are those.  A surface without split sides is that mesh's, whichever
    # refinement built it (an adaptive one whose leaves are all on the finest level has its
    # faces' ids), so the global steps give its spans.
    spans = Topology(patched_mesh(mesh, refinement="global")).face_spans
    faces = np.array([face for _, _, face, _ in surface.patches()], dtype=np.int64)
    if faces.size and faces.max() >= len(spans):
        raise ValueError("the surface's faces are not the mesh's: was it built from this mesh?")
    return spans[faces]
