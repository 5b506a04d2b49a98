"""Which patch corners and sides coincide, for a B-rep with shared topology.

Patches sit on the faces of nonzero parametric area.  A face whose interval is zero in u
(its edges h0, h2) collapses onto a curve: its vertices v0 ~ v1 and v3 ~ v2 coincide and its
sides h1 and h3 are one edge, run in opposite directions; zero in v likewise with v1 ~ v2,
v0 ~ v3 and h0 ~ h2.  Classes of mesh vertices and edges under these identifications are the
B-rep's vertices and edges.  Each half-edge runs along its edge (+1) or against it (-1); the
collapse links flip or keep that sign, so every side gets a direction relative to its class.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.errors import UnsupportedError
from patching.surface import PatchTopology
from patching.topology.tables import Topology

__all__ = ["patch_topology"]


def _classes(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n, n))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def patch_topology(topo: Topology, patch_faces: np.ndarray, spans: np.ndarray) -> PatchTopology:
    """Corner vertex ids, side edge ids and side directions of the patches on ``patch_faces``.

    spans: (f, 2) knot intervals of every face in u and v (zero: collapsed, no patch).
    """
    offsets = topo.mesh.face_offsets
    quad = np.diff(offsets) == 4
    zero_u = quad & (spans[:, 0] == 0)
    zero_v = quad & (spans[:, 1] == 0)
    base_u = offsets[np.flatnonzero(zero_u & ~zero_v)]
    base_v = offsets[np.flatnonzero(zero_v & ~zero_u)]
    base_uv = offsets[np.flatnonzero(zero_u & zero_v)]
    o = topo.origin
    # Vertex identifications.
    va = np.concatenate([o[base_u], o[base_u + 3], o[base_v + 1], o[base_v], o[base_uv], o[base_uv], o[base_uv]])
    vb = np.concatenate([o[base_u + 1], o[base_u + 2], o[base_v + 2], o[base_v + 3], o[base_uv + 1], o[base_uv + 2], o[base_uv + 3]])
    vclass = _classes(topo.n_vertices, va, vb)
    # Edge identifications with their relative direction: h1 ~ -h3 (zero u), h0 ~ -h2 (zero v).
    e = topo.edge_of
    sign = np.where(o == topo.edges[e, 0], 1, -1)
    ha = np.concatenate([base_u + 1, base_v])
    hb = np.concatenate([base_u + 3, base_v + 2])
    eclass = _classes(topo.n_edges, e[ha], e[hb])
    # Parity of every edge relative to its class root (the smallest edge id of the class):
    # edge(hb) = -sign(ha) sign(hb) edge(ha) in direction.
    link_a, link_b = e[ha], e[hb]
    link_p = -sign[ha] * sign[hb]
    root = np.full(eclass.max() + 1 if eclass.size else 0, topo.n_edges, dtype=np.int64)
    np.minimum.at(root, eclass, np.arange(topo.n_edges))
    parity = np.zeros(topo.n_edges, dtype=np.int64)
    known = np.arange(topo.n_edges) == root[eclass]
    parity[known] = 1
    for _ in range(link_a.size + 1):
        todo_ab = known[link_a] & ~known[link_b]
        todo_ba = known[link_b] & ~known[link_a]
        if not (todo_ab.any() or todo_ba.any()):
            break
        parity[link_b[todo_ab]] = parity[link_a[todo_ab]] * link_p[todo_ab]
        known[link_b[todo_ab]] = True
        parity[link_a[todo_ba]] = parity[link_b[todo_ba]] * link_p[todo_ba]
        known[link_a[todo_ba]] = True
    conflict = known[link_a] & known[link_b] & (parity[link_b] != parity[link_a] * link_p)
    if conflict.any():
        h = int(ha[np.flatnonzero(conflict)[0]])
        raise UnsupportedError(
            "zero knot intervals collapse a strip onto itself with a twist",
            f"face {int(topo.face[h])}",
        )

    sides = offsets[patch_faces][:, None] + np.arange(4)[None, :]  # (p, 4) half-edges
    corner = vclass[o[sides]]
    side_class = eclass[e[sides]]
    direction = sign[sides] * parity[e[sides]]
    # Compact ids over the classes the patches use, in order of first use.
    corner_ids = _renumber_by_first_use(corner.ravel())
    edge_ids = _renumber_by_first_use(side_class.ravel())
    n_edges = int(edge_ids.max()) + 1 if edge_ids.size else 0
    first_use = np.full(n_edges, -1, dtype=np.int64)
    flat_dir = direction.ravel()
    order = np.arange(edge_ids.size)[::-1]
    first_use[edge_ids[order]] = order  # lowest flat index wins
    reversed_ = flat_dir != flat_dir[first_use[edge_ids]]
    return PatchTopology(
        corner_vertex=corner_ids.reshape(-1, 4),
        side_edge=edge_ids.reshape(-1, 4),
        side_reversed=reversed_.reshape(-1, 4),
        n_vertices=int(corner_ids.max()) + 1 if corner_ids.size else 0,
        n_edges=n_edges,
    )


def _renumber_by_first_use(ids: np.ndarray) -> np.ndarray:
    """Map ids to 0..k-1 in order of first appearance."""
    uniq, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    rank = np.empty(uniq.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(uniq.size)
    return rank[inverse.ravel()]
