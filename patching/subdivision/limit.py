"""Limit points and tangents of the subdivision surface at the control vertices: refine until
every rule is stationary (semi-sharp features decayed), then the dominant left eigenvectors of
the local subdivision matrix ([TLC] sec. 3, [LFS16]; OpenSubdiv's limit masks for its rules)."""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from patching.errors import UnsupportedError
from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.rules.catmark import (
    CORNER,
    CREASE,
    DART,
    curve_derivative_weights,
    curve_limit_weights,
)

from patching.subdivision.catmark import _operator, _resolve
from patching.subdivision.child_mesh import _child_mesh
from patching.subdivision.context import _Context
from patching.util.sparse_rows import TripletRows

__all__ = ["limit_operator", "limit_points", "limit_tangents", "MAX_LIMIT_STEPS", "MAX_LIMIT_FACES"]


#: Most steps ``limit_operator`` takes to let semi-sharp features decay (1 + ceil(sharpness)).
MAX_LIMIT_STEPS = 6
#: Largest refined mesh (faces) ``limit_operator`` builds on the way.
MAX_LIMIT_FACES = 4_000_000


def _refine_for_limit(mesh: ControlMesh, rules: str, angles: str, crease_method: str = "uniform"):
    """Subdivide until every rule is stationary: one step (so that every vertex sees equal
    intervals on both halves of each spoke, [TLC] Fig. 8) plus one per unit of the largest
    finite sharpness.  Returns (level mesh, S_total, ids of the input vertices at that level)."""
    finite = [x for x in list(mesh.creases.values()) + list(mesh.corners.values()) if x < INFINITELY_SHARP]
    largest = max(finite, default=0.0)
    steps = 1 + int(math.ceil(largest))
    faces = mesh.n_faces * 4**steps
    # Two refusals, each naming its own cause: the face budget alone can be exceeded by a
    # large mesh with no finite sharpness at all (then there is no "largest sharpness").
    if steps > MAX_LIMIT_STEPS:
        raise UnsupportedError(
            f"limit of a semi-sharp feature of sharpness {largest:g} needs {steps} steps "
            f"({faces} faces); this version takes at most {MAX_LIMIT_STEPS} steps",
            mesh.name,
        )
    if faces > MAX_LIMIT_FACES:
        why = f"1 plus {steps - 1} for sharpness {largest:g} to decay" if finite else "no finite sharpness"
        raise UnsupportedError(
            f"limit of {mesh.n_faces} faces needs {steps} subdivision step(s) ({why}), "
            f"{faces} faces; this version builds at most {MAX_LIMIT_FACES} faces",
            mesh.name,
        )
    total = sp.identity(mesh.n_vertices, format="csr")
    ids = np.arange(mesh.n_vertices)
    for _ in range(steps):
        ctx = _Context(mesh, crease_method)
        s = _operator(ctx, rules, angles)
        total = (s @ total).tocsr()
        ids = ctx.nf + ctx.ne + ids
        mesh = _child_mesh(ctx, s @ mesh.vertices)
    return mesh, total, ids


def _spokes(ctx: _Context, v: np.ndarray):
    s0 = ctx.topo.outgoing[v]
    s1 = ctx.topo.rotate(s0)
    s2 = ctx.topo.rotate(s1)
    s3 = ctx.topo.rotate(s2)
    return s0, s1, s2, s3


def _local_masks(ctx: _Context, ids: np.ndarray, rules: str, angles: str, tangents: bool):
    """Limit (or tangent) masks at vertices ``ids`` of a stationary level: lists of
    (row-of-ids, cols, weights) triplets for position, tangent 1, tangent 2; and a mask of the
    rows whose tangents are undefined (corners, creases across, seed-rule darts of valence != 4)."""
    from patching.rules import eigen_polyhedron as eig

    lev = ctx.parent
    rule = lev.rule[ids]
    out = [TripletRows(), TripletRows(), TripletRows()]
    undefined = np.zeros((ids.size, 2), bool)
    k = np.arange(ids.size)

    corner = rule == CORNER
    out[0].add(k[corner], ids[corner], 1.0)
    undefined[corner] = True

    cr = np.flatnonzero(rule == CREASE)
    if cr.size:
        v = ids[cr]
        e0, e1 = lev.crease_edges[v, 0], lev.crease_edges[v, 1]
        end0 = np.where(ctx.edges[e0, 0] == v, ctx.edges[e0, 1], ctx.edges[e0, 0])
        end1 = np.where(ctx.edges[e1, 0] == v, ctx.edges[e1, 1], ctx.edges[e1, 0])
        a, b = ctx.d_e[e0], ctx.d_e[e1]
        for rows, w in ((out[0], curve_limit_weights(a, b)), (out[1], curve_derivative_weights(a, b))):
            rows.add(cr, end0, w[0])
            rows.add(cr, v, w[1])
            rows.add(cr, end1, w[2])
        undefined[cr, 1] = True

    # Darts under seed rules: the edges and faces around them are BLZ- or seed-000-modified,
    # so the local matrix is neither Catmull-Clark's nor a tensor product: take the dominant
    # left eigenvector of S's own 1-ring block (closed at a stationary level).
    seed_dart = (rule == DART) & (rules == "seed")
    for i in np.flatnonzero(seed_dart).tolist():
        v = int(ids[i])
        ring = ctx.topo.one_ring(v)
        cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
        block = _ring_block(ctx, v, ring, rules, angles)
        w, vl = np.linalg.eig(block.T)
        j = int(np.argmin(np.abs(w - 1.0)))
        lim = np.real(vl[:, j])
        out[0].add(np.full(cols.size, i), cols, lim / lim.sum())
        undefined[i] = True
    smooth = (rule <= DART) & ~seed_dart
    reg = np.flatnonzero(smooth & (ctx.valence[ids] == 4) & ~ctx.v_boundary[ids])
    if reg.size:
        v = ids[reg]
        spokes = _spokes(ctx, v)
        d = [ctx.d_h[h] for h in spokes]
        E = [ctx.dest[h] for h in spokes]
        F = [ctx.dest[ctx.nxt[h]] for h in spokes]
        limA, limB = curve_limit_weights(d[2], d[0]), curve_limit_weights(d[3], d[1])
        derA, derB = curve_derivative_weights(d[2], d[0]), curve_derivative_weights(d[3], d[1])
        for rows, wa, wb in ((out[0], limA, limB), (out[1], derA, limB), (out[2], limA, derB)):
            mA, cA, pA = wa
            mB, cB, pB = wb
            rows.add(reg, v, cA * cB)
            rows.add(reg, E[0], pA * cB)
            rows.add(reg, E[2], mA * cB)
            rows.add(reg, E[1], cA * pB)
            rows.add(reg, E[3], cA * mB)
            rows.add(reg, F[0], pA * pB)
            rows.add(reg, F[1], mA * pB)
            rows.add(reg, F[2], mA * mB)
            rows.add(reg, F[3], pA * mB)

    odd = np.flatnonzero(smooth & (ctx.valence[ids] != 4) & ~ctx.v_boundary[ids])
    for i in odd.tolist():
        v = int(ids[i])
        ring = ctx.topo.one_ring(v)
        n = ring.size
        cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
        d = ctx.d_h[ring]
        if n == 2:  # Catmull-Clark's 1-ring matrix at any intervals (module docstring)
            out[0].add(np.full(cols.size, i), cols, np.array([2.0, 2.0, 2.0, 0.5, 0.5]) / 7.0)
            undefined[i] = True
            continue
        if ctx.uniform:  # Catmull-Clark's limit mask (OpenSubdiv's assignSmoothLimitMask)
            lim = np.concatenate([[n / (n + 5.0)], np.full(n, 4.0 / (n * (n + 5.0))), np.full(n, 1.0 / (n * (n + 5.0)))])
        else:
            lim = eig.limit_point_weights(d, angles=angles)
        out[0].add(np.full(cols.size, i), cols, lim)
        if tangents:
            tw = eig.tangent_weights(d if not ctx.uniform else np.ones(n), angles=angles)
            out[1].add(np.full(cols.size, i), cols, tw[0])
            out[2].add(np.full(cols.size, i), cols, tw[1])
    return out, undefined


def _ring_block(ctx: _Context, v: int, ring: np.ndarray, rules: str, angles: str) -> np.ndarray:
    """S's rows and columns of v's 1-ring [V, E_0.., F_0..] (S built once per level)."""
    ops = ctx.__dict__.setdefault("_operators", {})
    if (rules, angles) not in ops:
        ops[(rules, angles)] = _operator(ctx, rules, angles)
    s = ops[(rules, angles)]
    cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
    rows = np.concatenate([[ctx.nf + ctx.ne + v], ctx.nf + ctx.eoh[ring], ctx.face[ring]])
    return s[rows][:, cols].toarray()


def limit_operator(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str | None = None
) -> sp.csr_matrix:
    """L: (n_vertices, n_vertices) CSR, ``L @ P`` = the limit-surface point of every vertex.

    Subdivides until the rules are stationary (``_refine_for_limit``), then applies the local
    limit masks: corner ``V``; crease ``curve_limit_weights`` along the crease (uniform
    (1, 4, 1)/6); regular smooth vertex the tensor product of the curve limit masks (the
    NURBS point); uniform EP Catmull-Clark's ``(n^2 V + 4 sum E + sum F) / (n (n + 5))``;
    non-uniform EP the dominant left eigenvector of the eigen-polyhedron matrix
    (``eigen_polyhedron.limit_point_weights``, [FSLYJ] sec. 3.5 step 2); a seed-rule dart
    of valence != 4 (BLZ-modified edges) the left eigenvector of S's own 1-ring block.
    Isolated vertices: themselves.
    """
    crease_method = _resolve(mesh, rules, angles, crease_method)
    level, total, ids = _refine_for_limit(mesh, rules, angles, crease_method)
    ctx = _Context(level)
    used = ctx.topo.vertex_is_used[ids]
    (pos, _, _), _ = _local_masks(ctx, ids[used], rules, angles, tangents=False)
    lim = (pos.matrix((int(used.sum()), level.n_vertices)) @ total).tocoo()
    rows_used = np.flatnonzero(used)
    iso = np.flatnonzero(~used)
    r = np.concatenate([rows_used[lim.row], iso])
    c = np.concatenate([lim.col, iso])
    v = np.concatenate([lim.data, np.ones(iso.size)])
    return sp.csr_matrix((v, (r, c)), shape=(mesh.n_vertices, mesh.n_vertices))


def limit_points(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str | None = None
) -> np.ndarray:
    """(n_vertices, 3) limit-surface position of every control vertex (``limit_operator``)."""
    return limit_operator(mesh, rules, angles, crease_method) @ mesh.vertices


def limit_tangents(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str | None = None
) -> np.ndarray:
    """(n_vertices, 2, 3) two tangent vectors of the limit surface at every vertex; NaN where the
    surface has no single tangent plane or this version does not compute it (corners; the
    second vector at crease vertices, where only the crease direction is given; seed-rule darts
    of valence != 4; interior vertices of valence 2, where Catmull-Clark's eigenvalue -1/4
    matches the subdominant 1/4 in modulus; isolated vertices).

    Regular vertex: parametric derivatives of the NURBS limit along the spokes ``E_0`` and
    ``E_1`` (``curve_derivative_weights``; first x second points along the faces' normal).
    EP: ``eigen_polyhedron.tangent_weights`` (derivatives along the eigen-polyhedron's axes,
    Catmull-Clark's eigenvectors for uniform intervals).  Crease: the derivative along the
    crease curve, from its first crease edge to its second.
    """
    crease_method = _resolve(mesh, rules, angles, crease_method)
    level, total, ids = _refine_for_limit(mesh, rules, angles, crease_method)
    ctx = _Context(level)
    used = ctx.topo.vertex_is_used[ids]
    rows_used = np.flatnonzero(used)
    (_, t1, t2), undefined = _local_masks(ctx, ids[used], rules, angles, tangents=True)
    out = np.full((mesh.n_vertices, 2, 3), np.nan)
    P = total @ mesh.vertices
    for j, rows in enumerate((t1, t2)):
        vec = rows.matrix((rows_used.size, level.n_vertices)) @ P
        vec[undefined[:, j]] = np.nan
        out[rows_used, j] = vec
    return out
