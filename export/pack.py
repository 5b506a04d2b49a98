"""Packed faces: rectangular blocks of bicubic patches as one multi-span B-spline face.

A regular region of the surface is, by construction (docs/knots.md, 3), one non-uniform bicubic
B-spline; ``to_shape`` nevertheless makes one Bézier face per patch.  Here blocks of bicubic
patches that lie in a rectangular grid become one ``Geom_BSplineSurface`` face each, re-using
the patches' coefficients only (no geometry rule is recomputed):

1. Blocks.  From a seed patch the block grows along its s direction across side 1 while the
   next patch is bicubic and free, then row by row across side 2 while every patch above is
   bicubic, free and the rows stay a grid (the patch right of each one is the next one above).
   Neighbours whose (s, t) frame is turned are turned to match (``np.rot90`` of the net, spans
   swapped).  A row or column that would close the block on itself (a full ring of a torus)
   is left out, so no packed face needs a seam.
2. Surface.  The block's nets become the poles of a bicubic B-spline with every interior knot
   of multiplicity 3 (the Bézier form: exactly the patches), knots at the cumulative knot
   intervals of the block's columns and rows (``Topology.face_spans``, the intervals
   the patches were extracted with), so that the joins are C2 in this parametrisation; then
   OpenCASCADE removes each interior knot down to multiplicity 1 (``RemoveUKnot``/
   ``RemoveVKnot``), which succeeds where the join is C2 to within ``KNOT_TOLERANCE``, else
   down to 2 (a C1 join, beside a zero interval).
3. Check.  The packed surface is evaluated at a 5 x 5 grid of every patch of the block and
   compared with the patch (de Casteljau via ``patching.evaluation.sampling.evaluate_nets``); a block
   that differs by more than ``EXACTNESS`` (relative to the surface size) is not packed
   (its patches stay Bézier faces), so the surface is never changed.
4. B-rep.  As ``export.brep.to_shape``, with shared vertices and edges: every patch side on a
   block's boundary keeps its own edge (so neighbours, packed or not, share it), with a
   degree-1 pcurve on the packed face from the side's start to its end in the block's (u, v):
   the B-spline restricted to one span is the patch reparametrised linearly, so SameParameter
   holds exactly.  Edges inside a block disappear.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from .ocp_compat import TColgp_Array2OfPnt
from .ocp_compat import TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.BRep import BRep_Builder
from OCP.Geom import Geom_BSplineSurface
from OCP.gp import gp_Pnt
from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
from OCP.TopoDS import TopoDS_Edge, TopoDS_Face, TopoDS_Shape, TopoDS_Vertex

from patching.bernstein import evaluate_nets
from patching.surface import CORNER_PARAMETERS, BezierSurface

from export.brep import (
    BrepError,
    bezier_curve,
    bezier_surface,
    line_2d,
    pcurve,
    side_row,
    assemble,
    bound_face,
    checked_patches,
    patch_components,
    no_volume_components,
    warn_no_volume,
    refuse_round_off,
    shape_tolerance,
)

__all__ = ["Block", "PackReport", "find_blocks", "patch_spans", "to_packed_shape"]

#: Knot removal tolerance (model units, times the surface size): C2 joins of patches computed
#: in double precision agree to ~1e-15; 1e-13 leaves room for round-off only.
KNOT_TOLERANCE = 1e-13
#: Largest allowed difference between a packed face and its patches, times the surface size.
EXACTNESS = 1e-12
#: Blocks have at most this many patches a side (keeps each face's pole grid moderate).
MAX_SIDE = 128


@dataclass(frozen=True)
class Block:
    """A w x h grid of patch rows: rows[i, j] is the patch at column i (along u), row j (along
    v); turns[i, j] how many quarter turns its net is rotated (side k of the block = the
    patch's original side (k + turns) mod 4); du (w,), dv (h,) the knot intervals."""

    rows: np.ndarray
    turns: np.ndarray
    du: np.ndarray
    dv: np.ndarray


def _neighbours(surface: BezierSurface) -> np.ndarray:
    """(p, 4, 2) int64: (row, side) across each side; (-1, -1) on a boundary, where an edge
    has other than two sides, or where both are one patch's (left unpacked)."""
    side_edge = np.asarray(surface.topology.side_edge, dtype=np.int64).ravel()
    out = np.full((side_edge.size, 2), -1, dtype=np.int64)
    by_edge = np.argsort(side_edge, kind="stable")
    uses = np.bincount(side_edge, minlength=int(side_edge.max()) + 1 if side_edge.size else 0)
    e = side_edge[by_edge]
    starts = (e[:-1] == e[1:]) & (uses[e[:-1]] == 2)  # the two sides of an edge, sorted together
    first, second = by_edge[:-1][starts], by_edge[1:][starts]
    pair = first // 4 != second // 4
    a, b = first[pair], second[pair]
    out[a] = np.stack([b // 4, b % 4], axis=1)
    out[b] = np.stack([a // 4, a % 4], axis=1)
    return out.reshape(-1, 4, 2)


def find_blocks(surface: BezierSurface, spans: np.ndarray) -> list[Block]:
    """Rectangular blocks of at least 2 bicubic patches (module docstring, step 1).

    spans: (p, 2) float64, the knot intervals of each patch along its s and t.
    No side on a block's boundary faces a patch of the same block (a full ring of a torus,
    or a helix of patches on a twisted one), so that no packed face meets itself along a seam.
    Raises UnsupportedError for a surface with split sides (T-junctions)."""
    surface.topology.require_whole_sides("packing faces")
    p = surface.n_patches
    cubic = np.zeros(p, dtype=bool)
    offset = 0
    for g in surface.groups:
        cubic[offset : offset + len(g.faces)] = g.degree == 3
        offset += len(g.faces)
    nb = _neighbours(surface)
    free = cubic.copy()

    def across(row: int, turn: int, side: int):
        """(row, turn) of the patch across block side ``side`` of (row, turn), placed in the
        block's frame, or None."""
        r, s = nb[row, (side + turn) % 4]
        if r < 0:
            return None
        return int(r), int((s - (side + 2)) % 4)  # its side s plays the opposite block side

    def faces_block(cells, sides, block: set) -> bool:
        """True when a patch across one of ``sides`` of one of ``cells`` is in ``block``."""
        return any((x := across(r, t, k)) is not None and x[0] in block for r, t in cells for k in sides)

    blocks = []
    for seed in range(p):
        if not free[seed]:
            continue
        row0 = [(seed, 0)]
        taken = {seed}
        while len(row0) < MAX_SIDE:
            nxt = across(*row0[-1], 1)
            if nxt is None or not free[nxt[0]] or nxt[0] in taken:
                break
            # Its sides 0, 1, 2 stay on the block's boundary (or become inner sides towards
            # patches not yet taken): none may face the row itself (a ring closes at side 1).
            if faces_block([nxt], (0, 1, 2), taken | {nxt[0]}):
                break
            row0.append(nxt)
            taken.add(nxt[0])
        grid = [row0]
        while len(grid) < MAX_SIDE:
            above = [across(r, t, 2) for r, t in grid[-1]]
            if any(a is None or not free[a[0]] or a[0] in taken for a in above):
                break
            ids = [a[0] for a in above]
            if len(set(ids)) != len(ids):
                break
            # A grid: right of each patch above is the next one above.
            if any(across(*above[i], 1) != above[i + 1] for i in range(len(above) - 1)):
                break
            # The new row's outer sides: 2 of every patch, 3 of the first and 1 of the last.
            block = taken | set(ids)
            if faces_block(above, (2,), block) or faces_block(above[:1], (3,), block) or faces_block(above[-1:], (1,), block):
                break
            grid.append(above)
            taken.update(ids)
        if len(taken) < 2:
            continue
        rows = np.array([[r for r, _ in line] for line in grid], dtype=np.int64).T  # (w, h)
        turns = np.array([[t for _, t in line] for line in grid], dtype=np.int64).T
        span = spans[rows]  # (w, h, 2) in each patch's own frame
        odd = turns % 2 == 1
        du = np.where(odd, span[..., 1], span[..., 0])
        dv = np.where(odd, span[..., 0], span[..., 1])
        if not (np.allclose(du, du[:, :1], rtol=1e-12) and np.allclose(dv, dv[:1, :], rtol=1e-12)):
            continue  # not one knot grid: leave the patches alone
        free[rows.ravel()] = False
        blocks.append(Block(rows, turns, du[:, 0].copy(), dv[0, :].copy()))
    return blocks


def _packed_surface(block: Block, nets: list[np.ndarray], size: float):
    """The B-spline of a block (steps 2 and 3), or None if it is not the patches to EXACTNESS."""
    w, h = block.rows.shape
    turned = np.empty((w, h, 4, 4, 3))
    for i in range(w):
        for j in range(h):
            turned[i, j] = np.rot90(nets[block.rows[i, j]], -int(block.turns[i, j]), axes=(0, 1))
    poles = TColgp_Array2OfPnt(1, 3 * w + 1, 1, 3 * h + 1)
    grid = np.empty((3 * w + 1, 3 * h + 1, 3))
    for i in range(w):
        for j in range(h):
            grid[3 * i : 3 * i + 4, 3 * j : 3 * j + 4] = turned[i, j]
    for a in range(3 * w + 1):
        for b in range(3 * h + 1):
            x, y, z = grid[a, b]
            poles.SetValue(a + 1, b + 1, gp_Pnt(float(x), float(y), float(z)))
    u = np.concatenate([[0.0], np.cumsum(block.du)])
    v = np.concatenate([[0.0], np.cumsum(block.dv)])

    def knots(values):
        k = TColStd_Array1OfReal(1, len(values))
        m = TColStd_Array1OfInteger(1, len(values))
        for i, x in enumerate(values):
            k.SetValue(i + 1, float(x))
            m.SetValue(i + 1, 4 if i in (0, len(values) - 1) else 3)
        return k, m

    uk, um = knots(u)
    vk, vm = knots(v)
    bspline = Geom_BSplineSurface(poles, uk, vk, um, vm, 3, 3, False, False)
    tol = KNOT_TOLERANCE * size
    # To multiplicity 1 (C2 join), else 2 (C1: a zero interval beside it, a double knot).
    for i in range(len(u) - 1, 1, -1):
        bspline.RemoveUKnot(i, 1, tol) or bspline.RemoveUKnot(i, 2, tol)
    for j in range(len(v) - 1, 1, -1):
        bspline.RemoveVKnot(j, 1, tol) or bspline.RemoveVKnot(j, 2, tol)
    # Step 3: the packed surface against every patch on a 5 x 5 grid.
    s = np.linspace(0.0, 1.0, 5)
    ss, tt = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))
    expected = evaluate_nets(turned.reshape(-1, 4, 4, 3), ss, tt)  # (w*h, 25, 3)
    got = np.array([
        bspline.Value(float(u[i] + a * block.du[i]), float(v[j] + b * block.dv[j])).Coord()
        for i in range(w) for j in range(h) for a, b in zip(ss, tt)
    ]).reshape(expected.shape)
    worst = float(np.linalg.norm(got - expected, axis=-1).max())
    if worst > EXACTNESS * max(size, 1e-300):
        return None, u, v
    return bspline, u, v


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


def to_packed_shape(surface: BezierSurface, spans: np.ndarray, *, check: bool = True) -> tuple[TopoDS_Shape, PackReport]:
    """The B-rep of ``surface`` with regular blocks packed (module docstring): a solid when
    closed, else a shell, checked by ``BRepCheck_Analyzer`` unless ``check`` is False.

    spans: (p, 2) knot intervals of every patch along its s and t (``patch_spans``).
    Raises UnsupportedError for a surface with split sides (T-junctions): blocks are found
    through one edge per side (``export.brep.to_shape`` builds those surfaces)."""
    topo = surface.topology
    topo.require_whole_sides("packing faces")
    nets = [net for _, _, _, net in checked_patches(surface, check)]  # to_shape's checks: bad input is refused alike
    tol = shape_tolerance(surface)
    builder = BRep_Builder()
    corner_vertex = np.asarray(topo.corner_vertex, dtype=np.int64)
    side_edge = np.asarray(topo.side_edge, dtype=np.int64)
    side_reversed = np.asarray(topo.side_reversed, dtype=bool)

    faces_plan = []  # ("patch", row) or ("block", block, bspline, u, v)
    in_block = np.zeros(len(nets), dtype=bool)
    for block in find_blocks(surface, spans):
        bspline, u, v = _packed_surface(block, nets, float(surface.size))
        if bspline is None:
            continue
        in_block[block.rows.ravel()] = True
        faces_plan.append(("block", block, bspline, u, v))
    faces_plan += [("patch", row) for row in range(len(nets)) if not in_block[row]]

    # Sides on a face boundary: every side of a lone patch, the outer sides of a block.
    used_sides: list[tuple[int, int]] = []
    for plan in faces_plan:
        if plan[0] == "patch":
            used_sides += [(plan[1], k) for k in range(4)]
        else:
            used_sides += [(r, (k + t) % 4) for r, t, k in _boundary(plan[1])]
    used_edges = {int(side_edge[r, k]) for r, k in used_sides}

    vertices: dict[int, TopoDS_Vertex] = {}

    def vertex(vid: int, point) -> TopoDS_Vertex:
        if vid not in vertices:
            v = TopoDS_Vertex()
            builder.MakeVertex(v, gp_Pnt(*(float(c) for c in point)), tol)
            vertices[vid] = v
        return vertices[vid]

    edges: dict[int, TopoDS_Edge] = {}
    for row, net in enumerate(nets):  # in row order, so an edge's curve is its first side's
        d = net.shape[0] - 1
        corners = (net[0, 0], net[d, 0], net[d, d], net[0, d])
        for k in range(4):
            eid = int(side_edge[row, k])
            if eid in edges or eid not in used_edges:
                continue
            rev = bool(side_reversed[row, k])
            curve_row = side_row(net, k)[::-1] if rev else side_row(net, k)
            e = TopoDS_Edge()
            builder.MakeEdge(e, bezier_curve(curve_row), tol)
            a, b = ((k + 1) % 4, k) if rev else (k, (k + 1) % 4)
            builder.Add(e, vertex(int(corner_vertex[row, a]), corners[a]).Oriented(TopAbs_FORWARD))
            builder.Add(e, vertex(int(corner_vertex[row, b]), corners[b]).Oriented(TopAbs_REVERSED))
            edges[eid] = e

    faces = []
    for plan in faces_plan:
        f = TopoDS_Face()
        if plan[0] == "patch":
            row = plan[1]
            builder.MakeFace(f, bezier_surface(nets[row]), tol)
            sides = [(row, k, pcurve(k, bool(side_reversed[row, k]))) for k in range(4)]
        else:
            _, block, bspline, u, v = plan
            builder.MakeFace(f, bspline, tol)
            sides = []
            for r, t, k, (i, j) in _boundary(block, with_cell=True):
                corner = lambda c: (u[i] + CORNER_PARAMETERS[c][0] * block.du[i], v[j] + CORNER_PARAMETERS[c][1] * block.dv[j])  # noqa: E731
                a, b = corner(k), corner((k + 1) % 4)
                original = (k + t) % 4
                if side_reversed[r, original]:
                    a, b = b, a
                sides.append((r, original, line_2d(a, b)))
        bound_face(builder, f, sides, edges, side_edge, side_reversed, tol)
        faces.append(f)

    # orientation as to_shape's test, without OCC's slow integration of multi-span faces
    face_rows = [plan[1] if plan[0] == "patch" else int(plan[1].rows.flat[0]) for plan in faces_plan]
    volumes = _component_volumes(surface)
    flat = no_volume_components(surface, volumes)
    order = iter([None if i in flat else v < 0.0 for i, v in enumerate(volumes.tolist())])
    shape = assemble(builder, list(edges.values()), faces, topo, lambda solid: next(order), face_rows)
    warn_no_volume(surface, *patch_components(topo), flat)
    if check:
        from OCP.BRepCheck import BRepCheck_Analyzer

        if not BRepCheck_Analyzer(shape).IsValid():
            refuse_round_off(surface)
            raise BrepError("BRepCheck_Analyzer rejects the packed B-rep")
    blocks = tuple((p[1], p[3], p[4]) for p in faces_plan if p[0] == "block")
    return shape, PackReport(len(faces), len(blocks), int(in_block.sum()), len(nets), blocks)


def _signed_volumes(surface: BezierSurface) -> np.ndarray:
    """Volume enclosed by each patch's cone to the origin, 1/3 of the integral of
    S . (S_s x S_t), by Gauss-Legendre with 10 nodes (exact for degree <= 5), in row order:
    summed over a closed component, its sign orients that solid."""
    x, weights = np.polynomial.legendre.leggauss(10)
    x, weights = (x + 1) / 2, weights / 2
    s, t = (a.ravel() for a in np.meshgrid(x, x, indexing="ij"))
    w = np.outer(weights, weights).ravel()
    out = []
    for g in surface.groups:
        p, ds, dt = evaluate_nets(g.coefficients, s, t, derivatives=True)
        out.append(np.einsum("m,kmc,kmc->k", w, p, np.cross(ds, dt)) / 3)
    return np.concatenate(out) if out else np.zeros(0)


def _component_volumes(surface: BezierSurface) -> np.ndarray:
    """(c,) signed volume of each closed component of the patches, in component order (the
    order in which ``assemble`` asks whether a solid is inside out): its orientation test and
    the no-volume check without OCC's slow integration of multi-span faces."""
    label, closed = patch_components(surface.topology)
    volumes = np.bincount(label, weights=_signed_volumes(surface), minlength=closed.size)
    return volumes[closed]


def _boundary(block: Block, with_cell: bool = False):
    """(row, turn, block side k[, (i, j)]) of the block's boundary, counter-clockwise: the
    bottom row's sides 0 left to right, the right column's sides 1 upwards, the top row's
    sides 2 right to left, the left column's sides 3 downwards."""
    w, h = block.rows.shape
    cells = [(i, 0, 0) for i in range(w)] + [(w - 1, j, 1) for j in range(h)]
    cells += [(i, h - 1, 2) for i in range(w - 1, -1, -1)] + [(0, j, 3) for j in range(h - 1, -1, -1)]
    for i, j, k in cells:
        item = (int(block.rows[i, j]), int(block.turns[i, j]), k)
        yield item + ((i, j),) if with_cell else item


def patch_spans(surface: BezierSurface, mesh) -> np.ndarray:
    """(p, 2) knot intervals of every patch along its s and t, from the mesh it was built from
    (``Topology.face_spans``: the intervals of the face's edges h0 and h1).  Wrong
    spans could not change the surface (a span of the triple-knot B-spline is its patch
    whatever its length), only keep knots from being removed."""
    from patching.operator import patched_mesh
    from patching.topology.tables import Topology

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
