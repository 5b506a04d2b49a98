"""The child mesh of one step: quads, knot intervals (halved, one per child strip) and
tags (sharpness decremented, OpenSubdiv's uniform or Chaikin creasing)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.topology.tables import Topology

from patching.subdivision.context import _Context


def _child_mesh(ctx: _Context, points: np.ndarray) -> ControlMesh:
    nf, ne = ctx.nf, ctx.ne
    h = np.arange(ctx.H)
    quads = np.stack(
        [nf + ne + ctx.origin, nf + ctx.eoh, ctx.face, nf + ctx.eoh[ctx.prv]], axis=1
    ).astype(np.int64)
    n_child = nf + ne + ctx.nv
    # Child edges: halves of parent edges (interval d/2, sharpness decremented) and the edges
    # F(face h) - E(edge h) inside a face (interval of the parallel parent edge, next(h), / 2).
    a, b = ctx.edges[:, 0], ctx.edges[:, 1]
    half_pairs = np.concatenate(
        [np.stack([nf + ne + a, nf + np.arange(ne)], 1), np.stack([nf + ne + b, nf + np.arange(ne)], 1)]
    )
    half_d = np.concatenate([ctx.d_e, ctx.d_e]) / 2.0
    inner_pairs = np.stack([ctx.face, nf + ctx.eoh], 1)
    inner_d = ctx.d_h[ctx.nxt[h]] / 2.0
    creases = {}
    es_child = ctx.child_es
    parent_s = ctx.topo.edge_sharpness
    for k, end in enumerate((a, b)):
        keep = np.flatnonzero((es_child[:, k] > 0) & ~ctx.e_boundary)
        for e in keep.tolist():
            s = float(parent_s[e]) if parent_s[e] >= INFINITELY_SHARP else float(es_child[e, k])
            pair = (nf + ne + int(end[e]), nf + e)
            creases[(min(pair), max(pair))] = s
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
    )
    # One interval per child strip (docs/knots.md: a value on one edge applies to its strip).
    ct = Topology(child)
    pairs = np.concatenate([half_pairs, inner_pairs])
    dvals = np.concatenate([half_d, inner_d])
    lo, hi = pairs.min(1), pairs.max(1)
    keys = ct.edges[:, 0] * n_child + ct.edges[:, 1]
    idx = np.searchsorted(keys, lo * n_child + hi)
    strip = ct.edge_strip[idx]
    first = np.full(ct.n_strips, -1, np.int64)
    first[strip[::-1]] = np.arange(strip.size)[::-1]
    value = dvals[first[strip]]
    if not np.allclose(value, dvals, rtol=1e-12, atol=0):
        raise AssertionError("child strips with two intervals (a bug: the non-quad check missed it)")
    reps = first[first >= 0]
    intervals = {(int(lo[i]), int(hi[i])): float(dvals[i]) for i in reps.tolist()}
    return replace(child, intervals=intervals)
