"""Evaluating patches: points, normals, blending functions, and a quality report per EP.

All vectorised over patches with Bernstein matrices; nets as in ``surface`` (net[i, j] times
B_i(s) B_j(t)).  The report per EP (``ep_quality``,) gives the largest normal
jump across its spoke edges and the number of local maxima of the blending functions around
it; maxima are counted on patch grids joined along shared corners and sides into one graph
(``sample_graph``), so a maximum at the EP or on a spoke is judged against every patch there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components
from patching.util.vectors import cross3

from patching.bernstein import bernstein, evaluate_nets
from patching.mesh.control_mesh import ControlMesh
from patching.surface import BezierSurface, SurfaceOperator
from patching.topology.tables import Topology

__all__ = [
    "evaluate_nets",
    "sample_surface",
    "normal_turning",
    "blending_function",
    "EPQuality",
    "ep_quality",
    "SampleGraph",
    "sample_graph",
    "column_values",
    "node_values",
    "local_maxima",
    "count_local_maxima",
    "blending_maxima",
    "blending_maxima_nodes",
    "spoke_normal_jumps",
    "prominences",
    "neighbourhood",
    "patch_rows",
]


def _grid_normals(nets: np.ndarray, samples: int):
    """Points, unit normals and |S_s x S_t| of (k, d+1, d+1, 3) nets on the samples x samples
    grid (row-major, s first): (k, samples^2, 3), (k, samples^2, 3), (k, samples^2, 1)."""
    u = np.linspace(0.0, 1.0, samples)
    s, t = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    p, ds, dt = evaluate_nets(nets, s, t, derivatives=True)
    n = cross3(ds, dt)
    size = np.linalg.norm(n, axis=-1, keepdims=True)
    return p, n / np.maximum(size, 1e-300), size


def sample_surface(surface: BezierSurface, samples: int = 9):
    """Points and unit normals on a samples x samples grid of every patch.

    Returns (faces (p,), points (p, samples^2, 3), normals (p, samples^2, 3))."""
    faces, points, normals = [], [], []
    for g in surface.groups:
        p, n, _ = _grid_normals(g.coefficients, samples)
        faces.append(g.faces)
        points.append(p)
        normals.append(n)
    return np.concatenate(faces), np.concatenate(points), np.concatenate(normals)


#: ``normal_turning`` takes this many patches at a time: its per-sample arrays then stay a few
#: MB, reused, where all patches at once were ~1 GB of fresh pages on the pawn's 93k patches.
TURNING_CHUNK = 2048


def _grid_derivatives(nets: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """S_s and S_t of (k, d+1, d+1, 3) nets on the samples x samples grid, component first:
    (3, k, samples, samples) each, [c, :, a, b] at (s_a, t_b).  The tensor-product form, one
    direction at a time (S_s = d sum_ij B^{d-1}_i(s) B^d_j(t) (N[i+1, j] - N[i, j]), S_t
    alike): two BLAS products per derivative, each result contiguous in that order."""
    d = nets.shape[1] - 1
    u = np.linspace(0.0, 1.0, samples)
    b, b1 = bernstein(d, u), bernstein(d - 1, u)
    comp = np.ascontiguousarray(nets.transpose(3, 0, 1, 2))  # (3, k, i, j)

    def grid(bs: np.ndarray, bt: np.ndarray, diff: np.ndarray) -> np.ndarray:
        # (3, k, i, j) . (a, i) -> (3, k, j, a); . (b, j) -> (3, k, a, b)
        return d * np.tensordot(np.tensordot(diff, bs, axes=([2], [1])), bt, axes=([2], [1]))

    return grid(b1, b, comp[:, :, 1:] - comp[:, :, :-1]), grid(b, b1, comp[:, :, :, 1:] - comp[:, :, :, :-1])


def normal_turning(
    surface: BezierSurface, samples: int = 25, singular: float = 1e-6, faces: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Fold detector: per patch, the smallest cosine between the unit normals of neighbouring
    samples of a samples x samples grid (along both grid lines).

    A patch that folds over itself stays G1 with its neighbours but its normal flips inside it
    (cosine near -1); a smooth patch sampled finely has cosines near 1.  A patch corner where
    |S_s x S_t| is below ``singular`` times the patch's largest (a degenerate corner, such as
    interpolateboundary 2 makes) has no normal and is left out: the normal is undefined there,
    not flipped.  Only corners: along a fold the Jacobian vanishes too, on a curve, and the
    flip across it must be seen.  faces: only the patches of these faces (default: all).
    Returns (faces (p,), min cosine (p,))."""
    corner = np.zeros((samples, samples), dtype=bool)
    corner[[0, 0, -1, -1], [0, -1, 0, -1]] = True
    out_faces, worst = [], []
    for g in surface.groups:
        keep = np.ones(len(g.faces), dtype=bool) if faces is None else np.isin(g.faces, faces)
        if not keep.any():
            continue
        nets = g.coefficients[keep] if faces is not None else g.coefficients
        out_faces.append(g.faces[keep])
        for start in range(0, nets.shape[0], TURNING_CHUNK):
            (s0, s1, s2), (t0, t1, t2) = _grid_derivatives(nets[start : start + TURNING_CHUNK], samples)
            n = np.stack([s1 * t2 - s2 * t1, s2 * t0 - s0 * t2, s0 * t1 - s1 * t0])  # S_s x S_t, (3, k, a, b)
            size = np.sqrt(np.einsum("ckab,ckab->kab", n, n))
            n /= np.maximum(size, 1e-300)
            regular = size > singular * size.max(axis=(1, 2), keepdims=True)
            regular |= ~corner  # only the four corners may be singular
            cos_s = np.einsum("ckab,ckab->kab", n[:, :, 1:], n[:, :, :-1])
            cos_t = np.einsum("ckab,ckab->kab", n[:, :, :, 1:], n[:, :, :, :-1])
            along_s = np.where(regular[:, 1:] & regular[:, :-1], cos_s, 1.0).min(axis=(1, 2))
            along_t = np.where(regular[:, :, 1:] & regular[:, :, :-1], cos_t, 1.0).min(axis=(1, 2))
            worst.append(np.minimum(along_s, along_t))
    if not out_faces:
        return np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(out_faces), np.concatenate(worst)


def blending_function(operator: SurfaceOperator, control_point: int, samples: int = 17):
    """The blending function of one control point (column of M) as heights over every patch
    it touches: returns (faces (k,), values (k, samples, samples)) on a uniform grid."""
    column = operator.matrix[:, control_point].toarray().ravel()
    u = np.linspace(0.0, 1.0, samples)
    faces, values = [], []
    for g in operator.groups:
        d = g.degree
        block = column[g.row_offset : g.row_offset + g.n_rows].reshape(-1, d + 1, d + 1)
        touched = np.flatnonzero(np.abs(block).max(axis=(1, 2)) > 0)
        if touched.size == 0:
            continue
        b = bernstein(d, u)
        values.append(np.einsum("si,tj,kij->kst", b, b, block[touched]))
        faces.append(g.faces[touched])
    if not faces:
        return np.zeros(0, np.int64), np.zeros((0, samples, samples))
    return np.concatenate(faces), np.concatenate(values)


# -- the sample graph: patch grids joined along shared corners and sides ----------------------
#
# Local maxima of a function on a surface made of patches must be judged across patch
# boundaries: a maximum at an EP or on a spoke is a corner or side sample of several patches.
# Every patch gets the same m x m grid (s_a, t_b) = (a, b) / (m - 1); samples on a corner or
# side are identified with those of the other patches through the B-rep topology of the
# operator (``PatchTopology``: corner_vertex, side_edge, side_reversed), which is the mesh's
# half-edge structure after collapsing zero-interval strips.  Sample keys (one integer each):
#
#     corner c of patch r          -> corner_vertex[r, c]
#     k-th inner sample of side k' -> n_corner + (m - 2) side_edge[r, k'] + (k - 1),
#                                     k counted along the edge's own direction
#     inner sample (a, b)          -> n_corner + (m - 2) n_edges + (m - 2)^2 r + ...
#
# Inside a patch, sample (a, b) neighbours its 8 grid neighbours (4 along the grid lines and
# the 2 diagonals of each cell: a diagonal ridge then cannot pass for a maximum).  Identified
# samples pool their neighbours, so the EP's node has the neighbours from all n patches.  This
# is purely topological: it needs no 3D positions, no planar layout and no Delaunay step, and
# it is exact for any mesh the operator accepts.

#: Side k of a patch runs, on the m x m grid, through these (a, b) for k = 0 .. m-1 along the
#: side's own direction (surface.py: side 0 s: 0->1 at t=0; side 1 t: 0->1 at s=1; side 2
#: s: 1->0 at t=1; side 3 t: 1->0 at s=0).
def _side_samples(side: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.arange(m)
    last = np.full(m, m - 1)
    return {0: (k, 0 * k), 1: (last, k), 2: (m - 1 - k, last), 3: (0 * k, m - 1 - k)}[side]


@dataclass(frozen=True)
class SampleGraph:
    """Grids on the patches ``rows`` joined into one graph.

    rows: (p,) int64 patch rows (the order of ``operator.groups`` concatenated).
    node: (p, m, m) int64 node id of every sample (a, b) at (s, t) = (a, b) / (m - 1).
    pairs: (e, 2) int64 neighbouring nodes, each unordered pair once.
    n_nodes: number of distinct nodes.
    """

    rows: np.ndarray
    node: np.ndarray
    pairs: np.ndarray
    n_nodes: int

    @cached_property
    def neighbour_table(self):
        """``_neighbour_table(pairs)``, made once per graph."""
        return _neighbour_table(self.pairs)


def patch_rows(operator: SurfaceOperator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(faces (p,), degree (p,), row_of_face (f,)) over the patches in row order; row_of_face is
    -1 for faces without a patch."""
    faces = np.concatenate([g.faces for g in operator.groups]).astype(np.int64)
    degree = np.concatenate([np.full(len(g.faces), g.degree) for g in operator.groups])
    row_of_face = np.full(int(faces.max()) + 1 if faces.size else 0, -1, dtype=np.int64)
    row_of_face[faces] = np.arange(faces.size)
    return faces, degree, row_of_face


def sample_graph(operator: SurfaceOperator, rows: np.ndarray, samples: int = 17) -> SampleGraph:
    """The graph of ``samples`` x ``samples`` grids on the patches ``rows``, joined along shared
    corners and sides (see the comment above; vectorised over patches)."""
    if samples < 3:
        raise ValueError("need at least 3 samples per side")
    topo = operator.topology
    topo.require_whole_sides("the sample graph")  # keys sides by side_edge
    rows = np.asarray(rows, dtype=np.int64)
    m, p = samples, rows.size
    inner = m - 2
    n_corner, n_edges = topo.n_vertices, topo.n_edges
    a, b = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    key = n_corner + inner * n_edges + inner * inner * rows[:, None, None] + (a - 1) * inner + (b - 1)
    for side in range(4):
        sa, sb = _side_samples(side, m)
        k = np.arange(1, m - 1)
        reversed_ = topo.side_reversed[rows, side][:, None]
        along = np.where(reversed_, m - 1 - k, k)
        key[:, sa[1:-1], sb[1:-1]] = n_corner + inner * topo.side_edge[rows, side][:, None] + along - 1
    for corner, (ca, cb) in enumerate(((0, 0), (m - 1, 0), (m - 1, m - 1), (0, m - 1))):
        key[:, ca, cb] = topo.corner_vertex[rows, corner]
    _, node = np.unique(key, return_inverse=True)
    node = node.reshape(p, m, m)
    links = [
        (node[:, :-1, :], node[:, 1:, :]),
        (node[:, :, :-1], node[:, :, 1:]),
        (node[:, :-1, :-1], node[:, 1:, 1:]),
        (node[:, 1:, :-1], node[:, :-1, 1:]),
    ]
    i = np.concatenate([x.ravel() for x, _ in links])
    j = np.concatenate([y.ravel() for _, y in links])
    n_nodes = int(node.max()) + 1 if node.size else 0
    pair_key = np.sort(np.minimum(i, j) * n_nodes + np.maximum(i, j))
    pair_key = pair_key[np.r_[True, pair_key[1:] != pair_key[:-1]]]  # links on seams come twice
    pairs = np.stack([pair_key // n_nodes, pair_key % n_nodes], axis=1)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    return SampleGraph(rows, node, pairs, n_nodes)


def column_values(operator: SurfaceOperator, columns, rows: np.ndarray, samples: int = 17) -> np.ndarray:
    """Blending functions of control points ``columns`` (k,) on the grids of patches ``rows``:
    (p, samples, samples, k), value[r, a, b, c] at (s, t) = (a, b) / (samples - 1)."""
    columns = np.atleast_1d(np.asarray(columns, dtype=np.int64))
    rows = np.asarray(rows, dtype=np.int64)
    u = np.linspace(0.0, 1.0, samples)
    sub = operator.matrix[:, columns].tocsr()
    out = np.zeros((rows.size, samples, samples, columns.size))
    start = 0
    for g in operator.groups:
        d = g.degree
        count = len(g.faces)
        mine = np.flatnonzero((rows >= start) & (rows < start + count))
        if mine.size:
            local = rows[mine] - start
            idx = (g.row_offset + (d + 1) ** 2 * local[:, None] + np.arange((d + 1) ** 2)).ravel()
            nets = sub[idx].toarray().reshape(mine.size, d + 1, d + 1, columns.size)
            bern = bernstein(d, u)
            half = np.tensordot(bern, nets, axes=(1, 1))  # (s, k, j, c)
            out[mine] = np.tensordot(half, bern, axes=(2, 1)).transpose(1, 0, 3, 2)  # (k, s, t, c)
        start += count
    return out


def node_values(graph: SampleGraph, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values (p, m, m, k) on the grids -> (n_nodes, k) per node (the mean over the samples
    joined in it) and (k,) the largest disagreement between joined samples: round-off for a
    C0 surface, so also a check of the joins."""
    k = values.shape[-1]
    flat_node = graph.node.ravel()
    flat = values.reshape(-1, k)
    total = np.stack([np.bincount(flat_node, flat[:, c], minlength=graph.n_nodes) for c in range(k)], axis=1)
    count = np.bincount(flat_node, minlength=graph.n_nodes)
    mean = total / np.maximum(count, 1)[:, None]
    gap = np.abs(flat - mean[flat_node]).max(axis=0) if flat.size else np.zeros(k)
    return mean, gap


def _neighbour_table(pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Neighbours grouped by node: (nodes that have neighbours, start of each one's group,
    neighbour ids), for ``np.maximum.reduceat``."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    target = np.concatenate([pairs[:, 0], pairs[:, 1]])
    source = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.argsort(target, kind="stable")
    target, source = target[order], source[order]
    starts = np.flatnonzero(np.r_[True, target[1:] != target[:-1]]) if target.size else np.zeros(0, np.int64)
    return target[starts], starts, source


def _maxima_nodes(values: np.ndarray, pairs: np.ndarray, rel_tol: float, table=None) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, heights) of the discrete maxima (see ``local_maxima``), highest first; the node
    of a plateau is its highest one.  table: ``_neighbour_table(pairs)`` if already made."""
    values = np.asarray(values, dtype=np.float64)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    none = np.zeros(0, np.int64), np.zeros(0)
    if values.size == 0:
        return none
    tol = rel_tol * max(float(np.abs(values).max()), np.finfo(float).tiny)
    nodes_with, starts, source = table if table is not None else _neighbour_table(pairs)
    higher = np.full(values.size, -np.inf)
    if source.size:
        higher[nodes_with] = np.maximum.reduceat(values[source], starts)
    top = (values > tol) & (higher <= values + tol)
    idx = np.flatnonzero(top)
    if idx.size == 0:
        return none
    both = top[pairs[:, 0]] & top[pairs[:, 1]]
    local = np.full(values.size, -1, dtype=np.int64)
    local[idx] = np.arange(idx.size)
    link = pairs[both]
    graph = sp.coo_matrix((np.ones(len(link)), (local[link[:, 0]], local[link[:, 1]])), shape=(idx.size,) * 2)
    n_comp, label = connected_components(graph, directed=False)
    order = idx[np.lexsort((-values[idx], label))]  # by component, highest first
    first = np.unique(label[local[order]], return_index=True)[1]
    nodes = order[first]
    rank = np.argsort(-values[nodes], kind="stable")
    return nodes[rank], values[nodes[rank]]


def local_maxima(values: np.ndarray, pairs: np.ndarray, rel_tol: float = 1e-10) -> np.ndarray:
    """Heights of the local maxima of a function sampled at graph nodes, highest first.

    values: (N,) float64.  pairs: (e, 2) int64 neighbouring nodes.
    A node is a maximum if no neighbour exceeds it by more than tol = rel_tol max|values|
    (strict up to round-off) and its value is above tol (the zero plateau outside a support
    is not a maximum).  Such nodes joined by a neighbour pair form one (plateau) maximum, so
    a maximum that falls between two samples of equal height by symmetry counts once.
    """
    return _maxima_nodes(values, pairs, rel_tol)[1]


def count_local_maxima(values: np.ndarray, pairs: np.ndarray, rel_tol: float = 1e-10) -> int:
    """Number of local maxima (see ``local_maxima``) of values (N,) on a graph with pairs (e, 2)."""
    return int(local_maxima(values, pairs, rel_tol).size)


def _bernstein_derivatives(d: int, x: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Values, first and second derivatives of B^d_0..B^d_d at x, each (d+1,)."""
    b0 = bernstein(d, np.array([x]))[0]
    b1 = np.zeros(d + 1)
    b2 = np.zeros(d + 1)
    if d >= 1:
        low = bernstein(d - 1, np.array([x]))[0]
        b1[1:] += d * low
        b1[:-1] -= d * low
    if d >= 2:
        low = bernstein(d - 2, np.array([x]))[0]
        b2[2:] += d * (d - 1) * low
        b2[1:-1] -= 2 * d * (d - 1) * low
        b2[:-2] += d * (d - 1) * low
    return b0, b1, b2


def _newton_maximum(net: np.ndarray, start: np.ndarray, iterations: int = 40):
    """Newton's method on the gradient of the polynomial sum net[i, j] B_i(s) B_j(t) from
    ``start`` (its continuation beyond [0, 1]^2 included).  Returns (s, t) of a critical point
    with a negative definite Hessian, or None."""
    d = net.shape[0] - 1
    x = np.asarray(start, dtype=np.float64).copy()
    scale = max(float(np.abs(net).max()), np.finfo(float).tiny)
    for _ in range(iterations):
        bs, bt = _bernstein_derivatives(d, x[0]), _bernstein_derivatives(d, x[1])
        g = np.array([bs[1] @ net @ bt[0], bs[0] @ net @ bt[1]])
        h = np.array([[bs[2] @ net @ bt[0], bs[1] @ net @ bt[1]], [bs[1] @ net @ bt[1], bs[0] @ net @ bt[2]]])
        if np.abs(g).max() <= 1e-11 * scale:
            return x if np.linalg.eigvalsh(h).max() < 0 else None
        try:
            step = -np.linalg.solve(h, g)
        except np.linalg.LinAlgError:
            return None
        if np.linalg.eigvalsh(h).max() >= 0 or g @ step <= 0:
            step = 0.05 * g / np.linalg.norm(g)  # ascend until the Hessian is concave
        x = x + np.clip(step, -0.1, 0.1)
    return None


def _confirmed_maxima(operator: SurfaceOperator, graph: SampleGraph, column: int, values: np.ndarray) -> np.ndarray:
    """Heights of the local maxima of one blending function (node values (N,)), highest first
    (``_confirmed_maxima_nodes`` without the nodes)."""
    return _confirmed_maxima_nodes(operator, graph, column, values)[1]


def _confirmed_maxima_nodes(
    operator: SurfaceOperator, graph: SampleGraph, column: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, heights) of the local maxima of one blending function (node values (N,)),
    highest first.

    The discrete maxima of ``local_maxima`` are candidates.  The highest is a maximum (the
    function has a global one).  Each other candidate must be confirmed by the polynomial of
    a patch it lies on: Newton's method from its sample reaches a critical point with a
    negative definite Hessian inside that patch and within two grid steps of the sample;
    confirmed maxima at the same or neighbouring nodes are one.  This removes maxima that
    sampling alone makes (a flat ridge crossing the grid obliquely), which otherwise come and
    go with the grid size; it cannot find a bump narrower than the grid.
    """
    nodes, heights = _maxima_nodes(values, graph.pairs, 1e-10, graph.neighbour_table)
    if nodes.size <= 1:
        return nodes, heights
    m = graph.node.shape[1]
    step = 1.0 / (m - 1)
    flat = graph.node.ravel()
    degrees = np.concatenate([np.full(len(g.faces), g.degree) for g in operator.groups])
    starts = np.cumsum([0] + [len(g.faces) for g in operator.groups])
    adjacency = sp.coo_matrix(
        (np.ones(len(graph.pairs)), (graph.pairs[:, 0], graph.pairs[:, 1])), shape=(graph.n_nodes,) * 2
    ).tocsr()
    adjacency = adjacency + adjacency.T
    kept_nodes = [int(nodes[0])]
    candidates = [int(nodes[0])]
    kept = [float(heights[0])]
    for node, height in zip(nodes[1:].tolist(), heights[1:].tolist()):
        hit = None
        for sample in np.flatnonzero(flat == node).tolist():
            p, rest = divmod(sample, m * m)
            a, b = divmod(rest, m)
            row = int(graph.rows[p])
            gi = int(np.searchsorted(starts, row, side="right") - 1)
            d = int(degrees[row])
            first = operator.groups[gi].row_offset + (d + 1) ** 2 * (row - starts[gi])
            net = operator.matrix[first : first + (d + 1) ** 2, column].toarray().reshape(d + 1, d + 1)
            x = _newton_maximum(net, np.array([a, b]) * step)
            if x is None or np.abs(x - np.array([a, b]) * step).max() > 2 * step:
                continue
            if (x < -1e-9).any() or (x > 1 + 1e-9).any():
                continue
            ga, gb = np.clip(np.rint(x / step).astype(int), 0, m - 1)
            hit = int(graph.node[p, ga, gb])
            break
        if hit is None:
            continue
        near = set(adjacency[hit].indices.tolist()) | {hit}
        if any(k in near for k in kept_nodes):
            continue
        kept_nodes.append(hit)
        candidates.append(node)
        kept.append(height)
    return np.array(candidates, dtype=np.int64), np.array(kept)


def blending_maxima_nodes(
    operator: SurfaceOperator, graph: SampleGraph, column: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, heights) of the local maxima of the blending function of control point
    ``column`` given by its node values (N,) on ``graph``, highest first, each beyond the
    highest confirmed by Newton's method (as ``blending_maxima`` counts them); the nodes say
    where they are (pictures mark them)."""
    return _confirmed_maxima_nodes(operator, graph, int(column), np.asarray(values, dtype=np.float64))


def prominences(values: np.ndarray, graph: SampleGraph, nodes: np.ndarray, rel_tol: float = 1e-4) -> np.ndarray:
    """Topographic prominence of the maxima at ``nodes`` (k,) of a function sampled on a graph:
    how far one must descend from each to reach higher ground (its height minus that of the
    highest saddle joining it to a higher node; for equally high twins, to the other twin),
    inf for a unique highest node.  By bisection on the level L: is the node joined to higher
    ground inside the samples with values >= L (``connected_components`` on the edges whose
    lower end is >= L)?  To rel_tol times the largest |value|.
    """
    values = np.asarray(values, dtype=np.float64)
    nodes = np.asarray(nodes, dtype=np.int64)
    out = np.full(nodes.size, np.inf)
    if nodes.size == 0:
        return out
    scale = float(np.abs(values).max())
    edge_level = np.minimum(values[graph.pairs[:, 0]], values[graph.pairs[:, 1]])

    def joined(k: int, level: float, twin: int) -> bool:
        keep = edge_level >= level
        link = graph.pairs[keep]
        adjacency = sp.coo_matrix((np.ones(len(link)), (link[:, 0], link[:, 1])), shape=(values.size,) * 2)
        label = connected_components(adjacency, directed=False)[1]
        mine = label == label[k]
        return bool((twin >= 0 and mine[twin]) or values[mine].max() > values[k])

    for i, k in enumerate(nodes.tolist()):
        twin = -1
        if not (values > values[k]).any():
            twins = np.flatnonzero(values == values[k])
            twins = twins[twins != k]
            if twins.size == 0:
                continue  # the unique highest node
            twin = int(twins[0])
        lo, hi = 0.0, float(values[k] - values.min())
        while hi - lo > rel_tol * scale:
            mid = 0.5 * (lo + hi)
            if joined(k, values[k] - mid, twin):
                hi = mid
            else:
                lo = mid
        out[i] = hi
    return out


def blending_maxima(
    operator: SurfaceOperator, control_points, samples: int = 17, rows: np.ndarray | None = None
) -> dict[int, np.ndarray]:
    """For every control point: heights of the local maxima of its blending function over its
    whole support, highest first (a well-shaped function has exactly one).  Discrete maxima
    on the joined grids (``sample_graph``, ``local_maxima``), each beyond the highest
    confirmed by Newton's method on the patch polynomial (``_confirmed_maxima``).

    rows: patches to sample (default: every patch the control points touch); they must cover
    the supports, otherwise a maximum could hide on the rim.
    """
    control_points = np.atleast_1d(np.asarray(control_points, dtype=np.int64))
    if rows is None:
        rows = _touched_rows(operator, control_points)
    graph = sample_graph(operator, rows, samples)
    values, _ = node_values(graph, column_values(operator, control_points, rows, samples))
    return {int(c): _confirmed_maxima(operator, graph, int(c), values[:, k]) for k, c in enumerate(control_points)}


def _touched_rows(operator: SurfaceOperator, control_points: np.ndarray) -> np.ndarray:
    """Patch rows where any of the control points has a non-zero coefficient."""
    coeff_rows = np.unique(operator.matrix[:, control_points].tocoo().row)
    out = []
    start = 0
    for g in operator.groups:
        size = (g.degree + 1) ** 2
        mine = coeff_rows[(coeff_rows >= g.row_offset) & (coeff_rows < g.row_offset + g.n_rows)]
        out.append(start + np.unique((mine - g.row_offset) // size))
        start += len(g.faces)
    return np.concatenate(out).astype(np.int64)


# -- per-EP quality report --------------------------------------------------------------------

_SIDE_PARAMETERS = {
    0: lambda u: (u, 0 * u),
    1: lambda u: (1 + 0 * u, u),
    2: lambda u: (1 - u, 1 + 0 * u),
    3: lambda u: (0 * u, 1 - u),
}


def spoke_normal_jumps(surface: BezierSurface, topology: Topology, vertex: int, samples: int = 9) -> np.ndarray:
    """(n,) largest angle in degrees between the normals of the two patches along each spoke
    edge of ``vertex`` (counter-clockwise order of ``Topology.one_ring``), sampled at
    ``samples`` points from the vertex (included) to the far end (included).

    Side c of a face is its half-edge c (surface.py), so spoke h is side ``corner(h)`` of
    face(h) run from the vertex, and side ``corner(twin h)`` of the other face run towards it.
    """
    offsets = topology.mesh.face_offsets
    where = {}
    for gi, g in enumerate(surface.groups):
        for k, f in enumerate(g.faces.tolist()):
            where[f] = (gi, k)
    w = np.linspace(0.0, 1.0, samples)
    out = []
    for h in topology.one_ring(vertex).tolist():
        t = int(topology.twin[h])
        normals = []
        for half, u in ((h, w), (t, 1.0 - w)):
            f = int(topology.face[half])
            if f not in where:
                raise ValueError(f"face {f} next to vertex {vertex} has no patch")
            gi, k = where[f]
            s, tt = _SIDE_PARAMETERS[half - int(offsets[f])](u)
            _, ds, dt = evaluate_nets(surface.groups[gi].coefficients[k][None], s, tt, derivatives=True)
            normals.append(np.cross(ds[0], dt[0]))
        n1, n2 = normals
        angle = np.degrees(np.arctan2(np.linalg.norm(np.cross(n1, n2), axis=1), (n1 * n2).sum(axis=1)))
        out.append(float(angle.max()))
    return np.array(out)


@dataclass(frozen=True)
class EPQuality:
    """Per EP: vertex id, valence, largest normal jump (degrees) across its spoke edges,
    and the number of local maxima of the blending function of each neighbourhood control
    point over its whole support: the EP, its edge neighbours and its diagonal neighbours
    (the 2n + 1 points of the faces around it).  ``second_maximum`` gives, per control
    point, the height of its second-highest maximum over the highest (0 with one maximum),
    and ``prominence`` the largest prominence of any other maximum (the depth of the dip
    that separates it from higher ground, ``prominences``) over the highest value (0 with one
    maximum), to tell a visible bump from a ripple or from two hills joined by a shallow
    saddle; ``seam_gap`` the largest disagreement between joined samples (round-off: the
    sampled functions are continuous); ``fold`` the smallest cosine between the normals of
    neighbouring samples on the patches of its faces (``normal_turning``; below 0: a fold)."""

    vertex: int
    valence: int
    max_normal_jump_deg: float
    local_maxima: dict[int, int]
    second_maximum: dict[int, float]
    prominence: dict[int, float]
    seam_gap: float
    fold: float


def neighbourhood(topology: Topology, vertex: int) -> tuple[np.ndarray, np.ndarray]:
    """(edge neighbours (n,), diagonal neighbours (n,)) of a vertex of an all-quad mesh, in
    the order of its spokes: the far end of spoke i and the vertex opposite it in face i."""
    h = topology.one_ring(vertex)
    return topology.dest[h], topology.origin[topology.next[topology.next[h]]]


def ep_quality(
    operator: SurfaceOperator,
    mesh: ControlMesh,
    samples: int = 17,
    eps=None,
    topology: Topology | None = None,
) -> list[EPQuality]:
    """Quality report per extraordinary point, for the surface
    ``operator.evaluate(mesh.vertices)``.

    Normal jumps: both patches at every spoke edge evaluated with numpy (``spoke_normal_jumps``,
    ``samples`` points along the spoke).  Local maxima: every blending function of the EP and
    its 2n neighbours sampled on ``samples`` x ``samples`` grids of every patch it touches,
    the grids joined into one graph through the patch topology (``sample_graph``), discrete
    maxima found by ``local_maxima`` and each but the highest confirmed by Newton's method on
    its patch polynomial (``_confirmed_maxima``): a count is of true local maxima of the
    function, not of the grid, down to bumps about one grid step wide (samples=33 is safer
    than 17 at interval ratios near 20).  The count is over the function's whole support, not
    only the EP's n patches: the edge neighbours sit on the rim of those patches, where half of
    their neighbourhood would be missing.  Each function's secondary maxima also get their
    prominence (``prominences``), so a ripple is told from a hill.  eps: the vertices to report (default: the mesh's EPs;
    pass the forced ones of ``build_operator(force_extraordinary=...)`` explicitly).
    """
    topo = topology or Topology(mesh)
    eps = topo.extraordinary if eps is None else np.atleast_1d(np.asarray(eps, dtype=np.int64))
    surface = operator.evaluate(mesh.vertices)
    ring_faces = {v: topo.face[topo.one_ring(v)] for v in eps.tolist()}
    wanted = np.concatenate(list(ring_faces.values())) if ring_faces else np.zeros(0, np.int64)
    turning_faces, turning = normal_turning(surface, samples=samples, faces=wanted)
    turning_of = dict(zip(turning_faces.tolist(), turning.tolist()))
    report = []
    for v in eps.tolist():
        edge_nb, diagonal = neighbourhood(topo, v)
        points = np.concatenate([[v], edge_nb, diagonal]).astype(np.int64)
        rows = _touched_rows(operator, points)
        graph = sample_graph(operator, rows, samples)
        values, gap = node_values(graph, column_values(operator, points, rows, samples))
        maxima, second, prominence = {}, {}, {}
        for k, c in enumerate(points.tolist()):
            nodes, heights = _confirmed_maxima_nodes(operator, graph, c, values[:, k])
            maxima[c] = int(heights.size)
            second[c] = float(heights[1] / heights[0]) if heights.size > 1 else 0.0
            if heights.size > 1:
                prominence[c] = float(prominences(values[:, k], graph, nodes[1:]).max() / heights[0])
            else:
                prominence[c] = 0.0
        jumps = spoke_normal_jumps(surface, topo, v, samples)
        report.append(
            EPQuality(
                vertex=int(v),
                valence=int(topo.valence[v]),
                max_normal_jump_deg=float(jumps.max()),
                local_maxima=maxima,
                second_maximum=second,
                prominence=prominence,
                seam_gap=float(gap.max()),
                fold=min((turning_of[f] for f in ring_faces[v].tolist() if f in turning_of), default=1.0),
            )
        )
    return report
