"""The Topology of a Catmull-Clark step's child mesh, derived from the parent's tables.

``Topology(child)`` sorts every child half-edge by its edge key, checks the manifold fans with a
graph search and finds the strips with another one: at every level, on a mesh four times the
parent's size.  The child of a manifold mesh is manifold, and its tables follow from the
parent's by index arithmetic (as OpenSubdiv's ``Vtr::QuadRefinement`` derives each level's
relations from the parent's), which ``child_topology`` does: equal array for array to
``Topology(child)`` (tests), without sorting.

Child numbering (``catmark``'s, OpenSubdiv's): face points ``f``, edge points ``nf + e``,
vertex points ``nf + ne + v``; child face ``h`` (one per parent half-edge) is
``(V(origin h), E(edge h), F(face h), E(edge prev h))``, so child half-edge ``4 h + j`` is its
corner j.  Child edges, numbered as ``Topology`` numbers them (by the key ``lo * n + hi``):

* the edge ``F(f) - E(e)`` inside face f for each of its edges e, the lower key (``f < nf``):
  ids ``0 .. H - 1``, face by face (``face_offsets[f]`` onwards), within a face by parent edge
  id; that of half-edge h's edge is ``inner[h]``;
* the halves ``E(e) - V(edges[e, k])``: id ``H + 2 e + k`` (``edges[e, 0] < edges[e, 1]``).

Twins: ``4h+1 <-> 4 next(h)+2`` inside a face; ``4h+0 <-> 4 next(twin h)+3`` across an edge.

Strips (``edge_strip``, docs/knots.md): in a child quad ``(V, E, F, E')`` each pair of opposite
edges has its lower end (E of ``V-E``, F of ``F-E'``; F of ``E-F``, E' of ``E'-V``) on one
side, the same rail of the strip: along every strip of a child mesh the first ends
``edges[:, 0]`` of its edges lie on one rail.  When the parent has that property (it is itself
a child, all quads: checked, not assumed), each parent strip s splits into exactly two child
strips, the halves at ``edges[e, k]`` with k = 0 and with k = 1 (and the inner edges parallel
to them), numbered ``2 s + k`` and then renumbered in the order of each strip's smallest edge,
as ``Topology``'s connected components number them.  A user's quad mesh splits its strips in
two as well, the sides found by a graph search on the halves of its edges (``split_strips``);
with non-quads (the first step only) the strips are left to ``Topology``'s own search on the
derived tables.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from patching.mesh.control_mesh import ControlMesh
from patching.topology.tables import Topology
from patching.util.graph import connected_components

__all__ = ["child_topology", "split_strips"]


def _inner_ids(t: Topology, face_offsets: np.ndarray) -> np.ndarray:
    """(H,) child edge id of ``F(face h) - E(edge h)``: the rank of (face, edge) pairs."""
    H = t.origin.size
    sizes = np.diff(face_offsets)
    if sizes.size and np.all(sizes == 4):
        e = t.edge_of.reshape(-1, 4)
        rank = np.empty(e.shape, np.int64)  # rank of e[:, i] among the face's four edges
        for i in range(4):
            r = face_offsets[:-1].copy()
            for j in range(4):
                if j != i:
                    r += e[:, j] < e[:, i]
            rank[:, i] = r
        return rank.ravel()
    order = np.argsort(t.face * max(t.n_edges, 1) + t.edge_of, kind="stable")
    out = np.empty(H, np.int64)
    out[order] = np.arange(H, dtype=np.int64)
    return out


def _child_outgoing(t: Topology, fsize: np.ndarray, tn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``vertex_outgoing`` of the child: from F(f) the half-edges ``4 h + 2`` of its face's
    corners, from E(e) ``4 h + 1`` and ``4 next(h) + 3`` for each half-edge h of e, from V(v)
    ``4 h`` for each h leaving v."""
    ptr_p, idx_p = t.vertex_outgoing
    H = t.origin.size
    h = t.edge_halfedge
    tw = t.twin[h]
    inside = tw >= 0
    e_out = np.stack([4 * h + 1, 4 * t.next[h] + 3, 4 * tw + 1, 4 * tn[h] + 3], axis=1)
    e_count = np.where(inside, 4, 2)
    e_out = e_out.ravel()[(np.arange(4) < e_count[:, None]).ravel()] if not inside.all() else e_out.ravel()
    idx = np.concatenate([4 * np.arange(H, dtype=np.int64) + 2, e_out, 4 * idx_p])
    counts = np.concatenate([fsize, e_count, np.diff(ptr_p)])
    ptr = np.zeros(counts.size + 1, np.int64)
    np.cumsum(counts, out=ptr[1:])
    return ptr, idx


def split_strips(t: Topology) -> np.ndarray | None:
    """(e, 2) child strip group of the half of every parent edge at ``edges[e, k]`` for an
    all-quad parent (None otherwise): each parent strip splits into two child strips, one a
    side.  In a quad (h_0 .. h_3) the half of h_i at its origin and the half of h_{i+2} at its
    dest lie on one side.  When that half has the same k everywhere (the parent is itself a
    child: module docstring) the groups are ``2 s + k``; otherwise (a user's quad mesh) the
    sides are the components of the graph of those links on the 2 e halves."""
    fo = t.mesh.face_offsets
    if t.n_faces == 0 or not np.all(np.diff(fo) == 4):
        return None
    k_orig = (t.edges[t.edge_of, 1] == t.origin).reshape(-1, 4)
    if np.array_equal(k_orig[:, :2], 1 - k_orig[:, 2:]):
        return 2 * t.edge_strip[:, None] + np.arange(2)
    e = t.edge_of.reshape(-1, 4)
    at_origin = 2 * e + k_orig
    at_dest = 2 * e + 1 - k_orig
    a = at_origin.ravel()
    b = at_dest[:, [2, 3, 0, 1]].ravel()
    n = 2 * t.n_edges
    _, label = connected_components(sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)
    return label.astype(np.int64).reshape(-1, 2)


def child_topology(t: Topology, child: ControlMesh, group: np.ndarray | None | bool = False) -> Topology | None:
    """The child mesh's Topology from the parent's ``t`` (module docstring), or None where the
    derivation does not apply (a face bordering itself across an edge: ``Topology(child)``
    then merges what the index arithmetic keeps apart).  group: ``split_strips(t)`` if the
    caller has it (False: computed here)."""
    tw = t.twin
    inside = tw >= 0
    if np.any(t.face[tw[inside]] == t.face[inside]):
        return None
    nf, ne, nv = t.n_faces, t.n_edges, t.n_vertices
    H = t.origin.size
    fo = t.mesh.face_offsets
    nxt, prv, eoh = t.next, t.prev, t.edge_of
    h = np.arange(H, dtype=np.int64)
    inner = _inner_ids(t, fo)
    k_orig = (t.edges[eoh, 1] == t.origin).astype(np.int64)  # half of edge(h) at origin(h)
    half_o = H + 2 * eoh + k_orig  # child edge V(origin h) - E(h)
    half_d = H + 2 * eoh + 1 - k_orig  # child edge E(h) - V(dest h)

    c = Topology.__new__(Topology)
    c.mesh = child
    c.n_faces, c.n_vertices = H, nf + ne + nv
    c.origin = child.face_vertices.astype(np.int64)
    h4 = np.arange(4 * H, dtype=np.int64)
    c.face = np.repeat(h, 4)
    c.next = h4 + np.tile(np.array([1, 1, 1, -3], np.int64), H)
    c.prev = h4 + np.tile(np.array([3, -1, -1, -1], np.int64), H)
    c.dest = c.origin[c.next]
    c.n_edges = H + 2 * ne
    edges = np.empty((c.n_edges, 2), np.int64)
    edges[inner, 0] = t.face
    edges[inner, 1] = nf + eoh
    edges[H:, 0] = nf + np.repeat(np.arange(ne, dtype=np.int64), 2)
    edges[H:, 1] = nf + ne + t.edges.ravel()
    c.edges = edges
    c.edge_of = np.stack([half_o, inner, inner[prv], half_d[prv]], axis=1).ravel()
    twin = np.empty((H, 4), np.int64)
    tn = nxt[np.maximum(tw, 0)]
    twin[:, 0] = np.where(inside, 4 * tn + 3, -1)
    twin[:, 1] = 4 * nxt + 2
    twin[:, 2] = 4 * prv + 1
    tp = tw[prv]
    twin[:, 3] = np.where(tp >= 0, 4 * tp, -1)
    c.twin = twin.ravel()
    eh = np.empty(c.n_edges, np.int64)
    eh[inner] = np.minimum(4 * h + 1, 4 * nxt + 2)
    eh[half_o] = np.where(inside, np.minimum(4 * h, 4 * tn + 3), 4 * h)
    eh[half_d] = np.where(inside, np.minimum(4 * nxt + 3, 4 * np.maximum(tw, 0)), 4 * nxt + 3)
    c.edge_halfedge = eh
    c.edge_is_boundary = c.twin[eh] < 0
    # cached vertex tables (Topology's cached_property names)
    fsize = np.diff(fo)
    eb = t.edge_is_boundary
    c.__dict__["valence"] = np.concatenate([fsize, 4 - eb.astype(np.int64), t.valence])
    c.__dict__["vertex_is_boundary"] = np.concatenate([np.zeros(nf, bool), eb, t.vertex_is_boundary])
    c.__dict__["vertex_is_used"] = np.concatenate([np.ones(nf + ne, bool), t.vertex_is_used])
    c.__dict__["vertex_outgoing"] = _child_outgoing(t, fsize, tn)
    if group is False:
        group = split_strips(t)
    if group is not None:
        # inner edge of h is parallel to next(h): the strip side of next(h)'s half at dest(h)
        g = np.empty(c.n_edges, np.int64)
        g[H:] = group.ravel()
        g[inner] = g[half_o[nxt]]
        n_groups = int(group.max()) + 1
        first = np.empty(n_groups, np.int64)  # smallest child edge of each group
        first[g[::-1]] = np.arange(c.n_edges - 1, -1, -1, dtype=np.int64)
        order = np.argsort(first, kind="stable")
        label = np.empty(n_groups, np.int64)
        label[order] = np.arange(n_groups, dtype=np.int64)
        strip_of_group = np.empty(n_groups, np.int64)
        strip_of_group[group.ravel()] = np.repeat(t.edge_strip, 2)
        c.__dict__["edge_strip"] = label[g]
        c.__dict__["n_strips"] = n_groups
        c.__dict__["strip_interval"] = (t.strip_interval / 2.0)[strip_of_group[order]]
    return c
