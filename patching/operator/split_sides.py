"""A ``PatchTopology`` with split sides from a table of T-junctions.

Feature-adaptive refinement (``patching.operator.adaptive``) leaves patches of different levels side
by side: a coarse patch side meets 2^k finer sides.  Its ``junctions`` table has a row per
pair of sides that meet,

    (coarse patch, coarse side, fine patch, fine side, u0, u1),

meaning the fine side covers [u0, u1] of the coarse side (u in the coarse side's direction,
0 at its corner k, 1 at corner k+1) and runs the other way; same-level pairs have u0 = 0,
u1 = 1 and are listed once.  Here every row becomes one B-rep edge: a whole piece [0, 1] on
the fine side, the piece [u0, u1] on the coarse side.  A side in no row lies on the open
boundary and gets an edge of its own.

Vertices come from a union-find over patch corners and break points (connected components of
a graph, vectorised): the fine side's start corner is the coarse side's point u1, its end
corner the point u0, where u = 0 and u = 1 are the coarse side's corners and 0 < u < 1 a
T-vertex.  Corners around an interior vertex are chained through the sides that meet there;
``corner_ids`` (optional, e.g. mesh vertex ids) joins corners that only a vertex links (a
pinch).  Ids are numbered in order of first use (vertices: corners row by row; edges: pieces
in side order), and an edge runs along its first whole-side piece, as ``PatchTopology``
requires; on a closed consistently oriented surface without T-junctions this is the topology
that ``patching.topology.patch_topology`` gives.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.surface import BezierSurface, PatchGroup, PatchTopology

__all__ = ["split_side_topology", "adaptive_surface", "adaptive_layout"]


def _first_use_ids(labels: np.ndarray) -> np.ndarray:
    """Renumber labels 0, 1, ... in order of first appearance."""
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inverse.ravel()]


def split_side_topology(n_patches: int, junctions: np.ndarray, corner_ids: np.ndarray | None = None) -> PatchTopology:
    """The shared topology of ``n_patches`` patches whose sides meet as ``junctions`` says.

    junctions: (k, 6) float64 rows (coarse patch, coarse side, fine patch, fine side, u0, u1),
        patch indices in row order (module docstring).
    corner_ids: optional (p, 4) int, corners with equal ids are one vertex.
    Returns a PatchTopology with the piece arrays set (``has_split_sides`` tells whether any
    side is split).  Raises ValueError where the rows do not tile a side exactly once.
    """
    p = int(n_patches)
    table = np.asarray(junctions, dtype=np.float64).reshape(-1, 6)
    k = len(table)
    coarse = table[:, 0].astype(np.int64) * 4 + table[:, 1].astype(np.int64)
    fine = table[:, 2].astype(np.int64) * 4 + table[:, 3].astype(np.int64)
    u0, u1 = table[:, 4], table[:, 5]
    if k and (min(coarse.min(), fine.min()) < 0 or max(coarse.max(), fine.max()) >= 4 * p):
        raise ValueError(f"junctions name patches or sides outside {p} patches x 4 sides")

    # Pieces: the coarse side's [u0, u1] and the fine side whole, then the boundary sides.
    used = np.zeros(4 * p, dtype=bool)
    used[coarse] = True
    used[fine] = True
    free = np.flatnonzero(~used)
    side = np.concatenate([coarse, fine, free])
    lo = np.concatenate([u0, np.zeros(k), np.zeros(free.size)])
    hi = np.concatenate([u1, np.ones(k), np.ones(free.size)])
    edge = np.concatenate([np.arange(k), np.arange(k), k + np.arange(free.size)])
    order = np.lexsort((lo, side))
    side, lo, hi, edge = side[order], lo[order], hi[order], edge[order]
    m = side.size

    # Each side tiled by its pieces exactly once.
    indptr = np.searchsorted(side, np.arange(4 * p + 1))
    first, last = indptr[:-1], indptr[1:] - 1
    follows = np.ones(m, dtype=bool)
    follows[first] = False
    bad = np.zeros(4 * p, dtype=bool)
    bad[side[follows & (np.r_[0.0, hi[:-1]] != lo)]] = True
    bad |= (lo[first] != 0.0) | (hi[last] != 1.0)
    bad[side[~(lo < hi)]] = True
    if bad.any():
        row, s = divmod(int(np.flatnonzero(bad)[0]), 4)
        raise ValueError(f"junctions cover side {s} of patch {row} with gaps or overlaps")

    # Vertices: corners 4 row + c, then break points (side, u) with 0 < u < 1.
    start_corner = np.arange(4 * p)
    end_corner = (start_corner // 4) * 4 + (start_corner + 1) % 4
    interior = np.concatenate([np.stack([coarse, u0], 1)[(u0 > 0) & (u0 < 1)], np.stack([coarse, u1], 1)[(u1 > 0) & (u1 < 1)]])
    breaks = np.unique(interior, axis=0) if interior.size else np.zeros((0, 2))

    def node(sides: np.ndarray, u: np.ndarray) -> np.ndarray:
        out = np.where(u == 0.0, start_corner[sides], end_corner[sides])
        mid = (u > 0.0) & (u < 1.0)
        if mid.any():
            keys = np.stack([sides[mid], u[mid]], 1)
            at = np.searchsorted(breaks[:, 0] * 2.0 + breaks[:, 1], keys[:, 0] * 2.0 + keys[:, 1])
            out[mid] = 4 * p + at  # breaks sorted by (side, u), u < 1: side * 2 + u is monotone
        return out

    a = [fine, end_corner[fine]]
    b = [node(coarse, u1), node(coarse, u0)]
    if corner_ids is not None:
        ids = np.asarray(corner_ids, dtype=np.int64).ravel()
        by_id = np.argsort(ids, kind="stable")
        same = ids[by_id[1:]] == ids[by_id[:-1]]
        a.append(by_id[1:][same])
        b.append(by_id[:-1][same])
    a, b = np.concatenate(a), np.concatenate(b)
    n_nodes = 4 * p + len(breaks)
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n_nodes, n_nodes))
    label = _first_use_ids(connected_components(graph, directed=False)[1])
    corner_vertex = label[: 4 * p].reshape(p, 4)
    piece_vertex = np.stack([label[node(side, lo)], label[node(side, hi)]], axis=1)

    # Edges: numbered by first use; each runs along its first whole piece (the fine side).
    edge = _first_use_ids(edge)
    n_edges = int(edge.max()) + 1 if m else 0
    whole = (lo == 0.0) & (hi == 1.0)
    index = np.arange(m)
    source = np.full(n_edges, 2 * m, dtype=np.int64)
    np.minimum.at(source, edge, np.where(whole, index, m + index))
    source = np.where(source >= m, source - m, source)
    piece_reversed = index != source[edge]  # the two pieces of an edge run opposite ways

    one = (last == first) & whole[first]
    side_edge = np.where(one, edge[first], -1).reshape(p, 4)
    side_reversed = (one & piece_reversed[first]).reshape(p, 4)
    return PatchTopology(
        corner_vertex=corner_vertex,
        side_edge=side_edge,
        side_reversed=side_reversed,
        n_vertices=int(label.max()) + 1 if label.size else 0,
        n_edges=n_edges,
        side_indptr=indptr.astype(np.int64),
        piece_edge=edge,
        piece_reversed=piece_reversed,
        piece_range=np.stack([lo, hi], axis=1),
        piece_vertex=piece_vertex,
    )


def adaptive_layout(patches) -> tuple[np.ndarray, np.ndarray]:
    """(order, table): the adaptive patch ids in row order (grouped by degree, ascending, ids
    ascending inside a degree, as ``AdaptivePatches.nets`` lists them) and the junction table
    with its patch ids mapped to those rows."""
    degree = np.asarray(patches.degree)
    order = np.concatenate([np.flatnonzero(degree == d) for d in np.unique(degree)] or [np.zeros(0, dtype=np.int64)])
    row = np.empty(patches.n_patches, dtype=np.int64)
    row[order] = np.arange(order.size)
    table = np.array(patches.junctions, dtype=np.float64).reshape(-1, 6)
    table[:, 0] = row[table[:, 0].astype(np.int64)]
    table[:, 2] = row[table[:, 2].astype(np.int64)]
    return order, table


def adaptive_surface(patches, points: np.ndarray, name: str = "adaptive", size: float | None = None) -> BezierSurface:
    """The ``BezierSurface`` of adaptive patches (``patching.operator.adaptive.AdaptivePatches``) on
    control points (n0, 3): one group per degree, ``faces`` = adaptive patch ids, topology
    from the junction table (``split_side_topology``, patch ids mapped to rows).

    size: the length tolerances are relative to (default: the control points' diagonal)."""
    points = np.asarray(points, dtype=np.float64)
    groups = []
    for degree, (ids, nets) in sorted(patches.nets(points).items()):
        spans = None if patches.spans is None else patches.spans[ids]
        groups.append(PatchGroup(int(degree), np.asarray(ids, dtype=np.int64), nets, spans))
    order, table = adaptive_layout(patches)
    if size is None:
        size = float(np.linalg.norm(np.ptp(points, axis=0))) if points.size else 0.0
    return BezierSurface(tuple(groups), split_side_topology(order.size, table), name, size)
