"""Pictures of blending functions ([FSLYJ] Figs. 1, 12, 13): the function of control point V
is column V of the operator M evaluated on the patches (coefficients = M @ P is linear in P,
so no rebuild per point: ``patching.evaluation.sampling.column_values``).

- On the surface: the function as a colour map on the patches, iso-lines (marching triangles
  over the picture's tessellation, ``iso_segments``) and its local maxima marked (those
  ``blending_maxima`` counts: discrete maxima of the patch grids joined across patch edges,
  each beyond the highest confirmed by Newton's method on the patch polynomial).
- As a graph (``--graph``): a height field z = B_V over a planar layout of the control mesh
  around V, as the paper draws them.  The layout is the mesh's own parametrisation made
  planar: a Tutte embedding of the faces of the support (the faces whose patches the
  function touches) with edge weights 1 / (knot interval), so that along a strip the layout's
  spacing follows the knot intervals (a harmonic 1D chain with weights 1/d_i spaces its
  points by d_i), the support's boundary fixed on the unit circle at arc lengths
  proportional to its knot intervals; each patch's (s, t) square is laid onto its face's
  quadrilateral bilinearly.  The control mesh's edges are drawn on the graph (the patches'
sides: each face's edges in the layout, lifted to the function's height).

``ep``: every extraordinary point's function, drawn as their pointwise maximum on the surface
(each one's maxima marked), and as graphs side by side.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from patching.errors import NupatchError, UnsupportedError
from patching.evaluation.sampling import (
    blending_maxima_nodes,
    column_values,
    node_values,
    sample_graph,
)
from patching.mesh import NupatchWarning
from patching.topology import Topology

from .render_geometry import grid_triangles
from .render_scene import Field, Sampled

__all__ = ["control_points", "graph_sampled", "iso_levels", "iso_segments", "region_layout", "surface_field"]

#: Height of the graph's peak, the layout being the unit disc.
GRAPH_HEIGHT = 0.7
#: Samples a patch side of the search for the maxima on the surface (``blending_maxima``'s).
SEARCH_SAMPLES = 17
#: Graphs side by side (``ep``): centre spacing in layout units.
GRAPH_SPACING = 2.5


def control_points(which: str, mesh, operator) -> np.ndarray:
    """Column ids of ``--blending V`` (an index) or ``ep`` (every EP), checked against M."""
    n = operator.matrix.shape[1]
    if which == "ep":
        eps = Topology(mesh).extraordinary
        if eps.size == 0:
            raise NupatchError(f"--blending ep: {mesh.name} has no extraordinary points", mesh.name)
        return eps.astype(np.int64)
    try:
        v = int(which)
    except ValueError:
        raise NupatchError(f"--blending takes a control-point index or 'ep', not '{which}'", "--blending") from None
    if not 0 <= v < n:
        raise NupatchError(f"--blending {v}: the mesh has {n} control points (0 to {n - 1})", "--blending")
    if operator.matrix[:, v].nnz == 0:
        raise NupatchError(f"--blending {v}: control point {v} has no blending function (no patch uses it)", "--blending")
    return np.array([v], dtype=np.int64)


def iso_levels(peak: float, count: int = 8) -> tuple[float, ...]:
    """Round iso-values (multiples of 1, 2 or 5 x 10^k) below ``peak``, about ``count`` of them."""
    if not (peak > 0 and math.isfinite(peak)):
        return ()
    raw = peak / (count + 1)
    power = 10.0 ** math.floor(math.log10(raw))
    step = min((m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw), default=10 * power)
    return tuple(float(f"{k * step:.12g}") for k in range(1, int(peak / step) + 1) if k * step < peak * (1 - 1e-9))


def iso_segments(points: np.ndarray, triangles: np.ndarray, values: np.ndarray, levels) -> np.ndarray:
    """(l, 2, 3) segments of the iso-lines values = level on a triangle mesh (marching
    triangles, linear along edges; vectorised over triangles)."""
    out = []
    f = np.asarray(values, dtype=float)[triangles]  # (t, 3)
    p = points[triangles]  # (t, 3, 3)
    for level in levels:
        above = f > level
        count = above.sum(axis=1)
        cut = (count == 1) | (count == 2)
        if not cut.any():
            continue
        fc, pc, ac = f[cut], p[cut], above[cut]
        ends = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            crosses = ac[:, i] != ac[:, j]
            w = (level - fc[:, i]) / np.where(crosses, fc[:, j] - fc[:, i], 1.0)
            ends.append((crosses, pc[:, i] + w[:, None] * (pc[:, j] - pc[:, i])))
        mask = np.stack([e[0] for e in ends], axis=1)  # exactly two True per row
        pts = np.stack([e[1] for e in ends], axis=1)
        order = np.argsort(~mask, axis=1, kind="stable")[:, :2]
        out.append(np.take_along_axis(pts, order[:, :, None], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 2, 3))


def _maxima(operator, columns: np.ndarray, m: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(patch rows, s, t) of the local maxima of every column's function (module docstring),
    searched on m x m grids of the patches ``rows`` (which must cover the supports)."""
    none = np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    try:
        graph = sample_graph(operator, rows, m)
    except UnsupportedError as exc:  # T-junctions: no joined grid to judge maxima across edges
        warnings.warn(NupatchWarning(f"local maxima not marked: {exc}"))
        return none
    values, _ = node_values(graph, column_values(operator, columns, rows, m))
    _, first = np.unique(graph.node.ravel(), return_index=True)  # a sample of every node
    found = [first[blending_maxima_nodes(operator, graph, c, values[:, k])[0]] for k, c in enumerate(columns.tolist())]
    if not found:
        return none
    p, rest = np.divmod(np.concatenate(found), m * m)
    a, b = np.divmod(rest, m)
    return rows[p], a / (m - 1), b / (m - 1)


def surface_field(operator, surface, sampled: Sampled, columns: np.ndarray, m: int, label: str) -> Sampled:
    """``sampled`` (``render.sample_surface`` of ``surface``, the operator's, with m samples a
    side) with the field of the blending functions of ``columns`` (module docstring); their
    maxima searched on ``SEARCH_SAMPLES`` a side, as ``blending_maxima`` does, and placed on
    the patches."""
    from dataclasses import replace

    from patching.bernstein import evaluate_pairs
    from patching.bernstein import common_nets

    rows = np.arange(sum(len(g.faces) for g in operator.groups), dtype=np.int64)
    values = column_values(operator, columns, rows, m)  # (p, m, m, k)
    field_values = values.max(axis=-1).reshape(-1)
    touched = rows[np.abs(values).reshape(len(rows), -1).max(axis=1) > 0]  # the supports
    r, s, t = _maxima(operator, columns, min(m, SEARCH_SAMPLES), touched)
    _, nets, _ = common_nets(surface)
    points, ds, dt = evaluate_pairs(nets[r], s, t, derivatives=True)
    normals = np.cross(ds, dt)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    peak = float(field_values.max())
    field = Field(field_values, label, "", points, iso_levels(peak), range=(0.0, peak), marker_normals=normals)
    return replace(sampled, field=field)


def region_layout(pm, region_faces: np.ndarray, name: str) -> dict[int, np.ndarray]:
    """Tutte layout (module docstring) of the faces ``region_faces`` of mesh ``pm``:
    {vertex: (2,) position}."""
    topo = Topology(pm)
    directed = {}
    for f in region_faces.tolist():
        vs = pm.face(f).tolist()
        for a, b in zip(vs, vs[1:] + vs[:1]):
            directed[(a, b)] = f
    boundary = {a: b for (a, b) in directed if (b, a) not in directed}
    if not boundary:
        raise NupatchError(f"--graph: the support covers a closed part of {name}; it has no planar layout", name)
    loops, seen = [], set()
    for start in boundary:
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen and v in boundary:
            seen.add(v)
            loop.append(v)
            v = boundary[v]
        loops.append(loop)
    outer = max(loops, key=len)
    vertices = sorted({v for (a, b) in directed for v in (a, b)})
    index = {v: i for i, v in enumerate(vertices)}

    def interval(a: int, b: int) -> float:
        return float(topo.edge_interval[topo.edge_id(a, b)])

    scale = max([interval(a, b) for (a, b) in directed] + [1e-300])
    lengths = np.array([max(interval(a, b), 1e-3 * scale) for a, b in zip(outer, outer[1:] + outer[:1])])
    angle = 2 * math.pi * np.concatenate([[0.0], np.cumsum(lengths)[:-1]]) / lengths.sum()
    fixed = {v: np.array([math.cos(t), math.sin(t)]) for v, t in zip(outer, angle)}
    n = len(vertices)
    rows, cols, data = [], [], []
    for (a, b) in directed:
        if (b, a) in directed and a > b:
            continue
        w = 1.0 / max(interval(a, b), 1e-3 * scale)
        i, j = index[a], index[b]
        rows += [i, j, i, j]
        cols += [j, i, i, j]
        data += [-w, -w, w, w]
    lap = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
    free = np.array([v not in fixed for v in vertices])
    pos = np.zeros((n, 2))
    for v, x in fixed.items():
        pos[index[v]] = x
    if free.any():
        a = lap[free][:, free].tocsc()
        rhs = -lap[free][:, ~free] @ pos[~free]
        pos[free] = np.column_stack([spsolve(a, rhs[:, 0]), spsolve(a, rhs[:, 1])])
    return {v: pos[index[v]] for v in vertices}


def graph_sampled(operator, mesh, columns: np.ndarray, m: int, label: str) -> Sampled:
    """The height fields of the blending functions of ``columns`` over their layouts (module
    docstring), side by side, as a Sampled with a field (z up)."""
    from patching import patched_mesh

    pm = patched_mesh(mesh)
    faces_of_rows = np.concatenate([g.faces for g in operator.groups]).astype(np.int64)
    n_rows = faces_of_rows.size
    u = np.linspace(0.0, 1.0, m)
    s, t = np.meshgrid(u, u, indexing="ij")
    weights = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], axis=-1)  # corners 0..3
    points, values, lines, markers, tri, base = [], [], [], [], [], 0
    per_row = column_values(operator, columns, np.arange(n_rows), m)  # (p, m, m, k)
    cols = max(1, math.ceil(math.sqrt(len(columns))))
    for k, c in enumerate(columns.tolist()):
        v = per_row[..., k]
        rows = np.flatnonzero(np.abs(v).reshape(n_rows, -1).max(axis=1) > 1e-12 * max(float(np.abs(v).max()), 1e-300))
        layout = region_layout(pm, faces_of_rows[rows], mesh.name)
        offset = GRAPH_SPACING * np.array([k % cols, -(k // cols)], dtype=float)
        peak = float(v[rows].max()) or 1.0
        corners = np.array([[layout[x] for x in pm.face(int(f)).tolist()] for f in faces_of_rows[rows]])  # (r, 4, 2)
        if corners.shape[1] != 4:
            raise NupatchError("--graph: the patched mesh has a non-quad face", mesh.name)
        xy = np.einsum("abc,rcd->rabd", weights, corners) + offset
        z = GRAPH_HEIGHT * v[rows] / peak
        pts = np.concatenate([xy, z[..., None]], axis=-1).reshape(-1, 3)
        points.append(pts)
        values.append(v[rows].reshape(-1))
        tri.append(grid_triangles(len(rows), m) + base)
        grid = pts.reshape(len(rows), m, m, 3)  # the faces' sides, lifted onto the graph
        sides = [grid[:, :, 0], grid[:, -1, :], grid[:, :, -1], grid[:, 0, :]]
        lines.append(np.concatenate([np.stack([x[:, :-1], x[:, 1:]], axis=2).reshape(-1, 2, 3) for x in sides]))
        r, s_, t_ = _maxima(operator, np.array([c]), m, rows)  # on the graph's own grid
        local = np.searchsorted(rows, r)
        markers.append(pts[local * m * m + np.rint(s_ * (m - 1)).astype(int) * m + np.rint(t_ * (m - 1)).astype(int)])
        base += len(pts)
    points = np.concatenate(points)
    triangles = np.concatenate(tri)
    normals = _vertex_normals(points, triangles)
    values = np.concatenate(values)
    zeros = np.zeros(len(points))
    field = Field(values, label, "", np.concatenate(markers), iso_levels(float(values.max())),
                  np.concatenate(lines), range=(0.0, float(values.max())))
    return Sampled(points, normals, zeros, zeros, triangles, np.zeros((0, 2, 3)), field=field)


def _vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals of a triangle mesh (the graph's shading)."""
    n = np.cross(points[triangles[:, 1]] - points[triangles[:, 0]], points[triangles[:, 2]] - points[triangles[:, 0]])
    out = np.zeros_like(points)
    for k in range(3):
        np.add.at(out, triangles[:, k], n)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
