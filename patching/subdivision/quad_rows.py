"""S of one uniform Catmull-Clark step of an all-quad mesh, written row by row in CSR order.

The general assembly (``catmark._operator``) gathers triplets rule by rule and lets scipy sort
them into rows and sum repeated entries.  With uniform knots on quads (every step after the
first, and most meshes' first) each row has a fixed shape, so the rows are written in place,
the arrays of ``indptr``, ``indices`` and ``data`` filled directly (no sort, no sum):

* face point f: the four corners, 1/4 each;
* edge point e (half-edge h = ``edge_halfedge[e]`` from a to b in face (a, b, c, x), twin
  in face (b, a, y, z)): ``a, b`` get ``w/2 + (1 - w) 3/8`` (plus BLZ's correction under
  the seed rules, +corr on a, -corr on b), ``c, x, y, z`` get ``(1 - w)/16``: the sharp
  midpoint blended with Catmull-Clark's smooth rule ``(a + b + F_0 + F_1)/4`` written on the
  parent points (each face point a quarter of its corners), w the sharp weight;
* vertex point v of valence n, outgoing half-edges h (``Topology.vertex_outgoing``): v, then
  ``dest(h)`` and the corner across the face ``dest(next h)`` for each h, then on the boundary
  the far end of the incoming boundary edge.  Smooth part (Catmull-Clark,
  ``(n-2)/n V + sum(E_j)/n^2 + sum(F_j)/n^2`` on the parent points): v ``(n-2)/n + 1/(4n)``,
  ``dest(h)`` ``3/(2n^2)`` (its edge, and a quarter from each of its two faces), the corner
  across ``1/(4n^2)``; crease part ``3/4 V + 1/8`` on the other ends of the two crease edges;
  corner part ``V``; each scaled by the vertex's blend of parent and child rule.

Entries a rule does not use stay as explicit zeros, and a column can repeat (two quads sharing
two edges): a product ``S @ P`` is the same; ``canonical`` sums repeats and drops zeros, giving
the matrix the triplet assembly gives (tests: equal to 1e-15, entry for entry)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from patching.rules.catmark import CORNER, CREASE

from patching.subdivision.context import _Context

__all__ = ["quad_operator"]


def quad_operator(
    ctx: _Context,
    w: np.ndarray,
    corr: np.ndarray,
    scales: tuple[np.ndarray, np.ndarray, np.ndarray],
    canonical: bool = True,
) -> sp.csr_matrix | None:
    """S as the module docstring writes it, or None where its row shapes do not apply (a
    non-quad face; a smooth rule at a boundary vertex or a smooth part on a boundary edge,
    which OpenSubdiv's boundary tags never give).  w (e,) the sharp weight of each edge
    point, corr (e,) BLZ's correction (zeros under OpenSubdiv's rules), scales the smooth,
    parent and child rule weights of each vertex point (``catmark._vertex_scales``)."""
    t = ctx.topo
    nf, ne, nv, H = ctx.nf, ctx.ne, ctx.nv, ctx.H
    if H != 4 * nf or not np.all(ctx.fsize == 4):
        return None
    sm, ps, cs = scales
    used = t.vertex_is_used
    vb = ctx.v_boundary
    sm = np.where(used, sm, 0.0)
    eb = ctx.e_boundary
    if np.any((sm > 0) & vb) or np.any(eb & (w != 1.0)):
        return None
    origin, dest, nxt, prv = ctx.origin, ctx.dest, ctx.nxt, ctx.prv
    ptr, out = t.vertex_outgoing
    count = np.diff(ptr)
    v_len = 1 + 2 * count + vb
    v_ptr = np.zeros(nv + 1, np.int64)
    np.cumsum(v_len, out=v_ptr[1:])
    # one array each for indices and data, filled block by block: faces, edges, vertices
    n_rows = nf + ne + nv
    e0, v0 = H, H + 6 * ne
    nnz = v0 + int(v_ptr[-1])
    idx_t = np.int32 if max(nnz, nv) < 2**31 else np.int64  # scipy's own choice, no copy
    indptr = np.empty(n_rows + 1, idx_t)
    indptr[:nf] = np.arange(0, H, 4)
    indptr[nf : nf + ne] = np.arange(e0, v0, 6)
    indptr[nf + ne :] = v0 + v_ptr
    indices = np.empty(nnz, idx_t)
    data = np.empty(nnz, np.float64)
    indices[:e0] = origin
    data[:e0] = 0.25

    # -- edge rows: a, b, c, x, y, z (boundary: y = z = a, weight 0) --------------------------
    h = t.edge_halfedge
    tw = ctx.twin[h]
    tw0 = np.maximum(tw, 0)
    inside = tw >= 0
    e_cols = indices[e0:v0].reshape(ne, 6)
    e_cols[:, 0] = a = origin[h]
    e_cols[:, 1] = dest[h]
    e_cols[:, 2] = dest[nxt[h]]
    e_cols[:, 3] = origin[prv[h]]
    e_cols[:, 4] = np.where(inside, dest[nxt[tw0]], a)
    e_cols[:, 5] = np.where(inside, origin[prv[tw0]], a)
    smooth = 1.0 - w
    mid = 0.5 * w + 0.375 * smooth
    e_vals = data[e0:v0].reshape(ne, 6)
    e_vals[:, 0] = mid + corr
    e_vals[:, 1] = mid - corr
    e_vals[:, 2:] = np.where(inside, 0.0625 * smooth, 0.0)[:, None]

    # -- vertex rows -----------------------------------------------------------------------------
    n = np.maximum(ctx.valence, 1).astype(np.float64)
    p_rule, c_rule = ctx.parent.rule, ctx.child.rule
    pc = np.where(p_rule == CREASE, ps, 0.0)
    cc = np.where(c_rule == CREASE, cs, 0.0)
    centre = (
        sm * ((n - 2.0) / n + 0.25 / n)
        + 0.75 * (pc + cc)
        + np.where(p_rule == CORNER, ps, 0.0)
        + np.where(c_rule == CORNER, cs, 0.0)
        + np.where(used, 0.0, 1.0)
    )
    v_cols, v_vals = indices[v0:], data[v0:]
    v_cols[v_ptr[:-1]] = np.arange(nv)
    v_vals[v_ptr[:-1]] = centre
    vo = origin[out]  # the vertex of each ring entry
    pos = (v_ptr[:-1] - 2 * ptr[:-1] + 1)[vo] + 2 * np.arange(out.size, dtype=np.int64)
    nn = n * n
    v_cols[pos] = dest[out]
    v_vals[pos] = (sm * 1.5 / nn)[vo]
    v_cols[pos + 1] = dest[nxt[out]]
    v_vals[pos + 1] = (sm * 0.25 / nn)[vo]
    inc = np.flatnonzero(ctx.twin < 0)  # incoming boundary half-edges: the far end, last
    far = v_ptr[dest[inc] + 1] - 1
    v_cols[far] = origin[inc]
    v_vals[far] = 0.0  # (crease part below)
    # crease part: 1/8 on the far end of each of the two crease edges of a crease vertex
    ring_pos = np.empty(H, np.int64)  # entry of dest(h) in the row of origin(h)
    ring_pos[out] = pos
    for scale, lev in ((pc, ctx.parent), (cc, ctx.child)):
        v = np.flatnonzero(scale > 0)
        for k in (0, 1):
            hh = t.edge_halfedge[lev.crease_edges[v, k]]
            tw_h = ctx.twin[hh]
            at = np.where(
                origin[hh] == v, ring_pos[hh], np.where(tw_h >= 0, ring_pos[np.maximum(tw_h, 0)], v_ptr[v + 1] - 1)
            )
            np.add.at(v_vals, at, 0.125 * scale[v])

    s = sp.csr_matrix((data, indices, indptr), shape=(n_rows, nv))
    if canonical:
        s.sum_duplicates()
        s.eliminate_zeros()
    return s
