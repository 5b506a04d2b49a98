"""The child mesh of one step: quads, knot intervals (halved, one per child strip) and
tags (sharpness decremented, OpenSubdiv's uniform or Chaikin creasing)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.topology.cache import remember
from patching.topology.tables import Topology

from patching.subdivision.child_topology import child_topology, split_strips

from patching.subdivision.context import _Context


def _child_mesh(ctx: _Context, points: np.ndarray) -> ControlMesh:
    nf, ne = ctx.nf, ctx.ne
    h = np.arange(ctx.H)
    quads = np.stack(
        [nf + ne + ctx.origin, nf + ctx.eoh, ctx.face, nf + ctx.eoh[ctx.prv]], axis=1
    ).astype(np.int64)
    # Child edges: halves of parent edges (interval d/2, sharpness decremented) and the edges
    # F(face h) - E(edge h) inside a face (interval of the parallel parent edge, next(h), / 2).
    creases = {}
    es_child = ctx.child_es
    parent_s = ctx.topo.edge_sharpness
    for k in (0, 1):
        keep = np.flatnonzero((es_child[:, k] > 0) & ~ctx.e_boundary)
        s = np.where(parent_s[keep] >= INFINITELY_SHARP, parent_s[keep], es_child[keep, k])
        creases.update(zip(zip((nf + keep).tolist(), (nf + ne + ctx.edges[keep, k]).tolist()), s.tolist()))
    corners = {}
    for v, s in ctx.mesh.corners.items():
        if s >= INFINITELY_SHARP:
            corners[nf + ne + v] = float(s)
        elif s > 1.0:
            corners[nf + ne + v] = float(s) - 1.0
    holes = frozenset(int(x) for x in h[np.isin(ctx.face, np.fromiter(ctx.mesh.holes, np.int64))]) if ctx.mesh.holes else frozenset()
    child = ControlMesh(
        vertices=np.ascontiguousarray(points, dtype=np.float64),
        face_vertices=quads.ravel(),
        face_offsets=np.arange(0, 4 * ctx.H + 1, 4, dtype=np.int64),
        intervals={},
        creases=creases,
        corners=corners,
        holes=holes,
        interpolate_boundary=ctx.mesh.interpolate_boundary,
        name=ctx.mesh.name,
        triangle_subdivision=ctx.mesh.triangle_subdivision,
        crease_method=ctx.crease_method,
    )
    # One interval per child strip (docs/knots.md: a value on one edge applies to its strip),
    # on the strip's first edge in the order (halves at edges[:, 0], halves at edges[:, 1],
    # inner edges).  When every parent strip splits into its two sides (``split_strips``), a
    # side's first edge is one of its halves: the half k of edge e comes k * ne + e-th.
    group = split_strips(ctx.topo)
    if group is not None:
        order_groups = np.concatenate([group[:, 0], group[:, 1]])
        first = np.empty(int(group.max()) + 1, np.int64)
        first[order_groups[::-1]] = np.arange(2 * ne - 1, -1, -1, dtype=np.int64)
        e, k = first % ne, first // ne
        intervals = dict(zip(zip((nf + e).tolist(), (nf + ne + ctx.edges[e, k]).tolist()), (ctx.d_e[e] / 2.0).tolist()))
        out = replace(child, intervals=intervals)
        parent = ctx.topo
        remember(out, lambda: _derived(parent, out, group))
        return out
    ct = _derived(ctx.topo, child, group)
    half = ctx.H + 2 * np.arange(ne, dtype=np.int64)
    idx = np.concatenate([half, half + 1, ct.edge_of[4 * h + 1]])  # child edge of each pair
    a, b = ctx.edges[:, 0], ctx.edges[:, 1]
    half_pairs = np.concatenate(
        [np.stack([nf + ne + a, nf + np.arange(ne)], 1), np.stack([nf + ne + b, nf + np.arange(ne)], 1)]
    )
    half_d = np.concatenate([ctx.d_e, ctx.d_e]) / 2.0
    inner_pairs = np.stack([ctx.face, nf + ctx.eoh], 1)
    inner_d = ctx.d_h[ctx.nxt[h]] / 2.0
    pairs = np.concatenate([half_pairs, inner_pairs])
    dvals = np.concatenate([half_d, inner_d])
    strip = ct.edge_strip[idx]
    first = np.full(ct.n_strips, -1, np.int64)
    first[strip[::-1]] = np.arange(strip.size)[::-1]
    value = dvals[first[strip]]
    if not np.allclose(value, dvals, rtol=1e-12, atol=0):
        raise AssertionError("child strips with two intervals (a bug: the non-quad check missed it)")
    reps = first[first >= 0]
    lo, hi = pairs[reps].min(1), pairs[reps].max(1)
    intervals = {(int(a), int(b)): float(d) for a, b, d in zip(lo.tolist(), hi.tolist(), dvals[reps].tolist())}
    out = replace(child, intervals=intervals)
    ct.mesh = out
    remember(out, ct)
    return out


def _derived(parent: Topology, child: ControlMesh, group: np.ndarray | None | bool = False) -> Topology:
    """The child's Topology from the parent's (``child_topology``), or built afresh."""
    ct = child_topology(parent, child, group)
    return Topology(child) if ct is None else ct
