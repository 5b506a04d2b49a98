"""A fourth placement of the auxiliary control points: fitted to the limit surface of the
non-uniform subdivision ([FSLYJ] sec. 3.6, Fig. 17: "the auxiliary points can also be
computed by approximating to some target surfaces ... approximating the limit subdivision
surface using the rule in [LFS16]").

The target: two steps of the seed's non-uniform Catmull-Clark rules (``subdivision``, [TLC]
with [LFS16]'s eigen-polyhedron rules at EPs), then the limit point of every level-2 vertex
(``subdivision.limit.limit_operator``).  Knots are inserted at the middle of every interval, so
a level-2 vertex inside or on face f sits at a parameter (a/4, b/4) of f's patch (a, b in
0..4; the parameters follow the child numbering: face points, edge points, vertex points,
each the centroid, midpoint or copy of its parents' parameters).  Per EP v, the anchors A_v
solve

    min_{A_v}  sum_{f in ring(v)} sum_{a, b} |S_f(a/4, b/4) - L_f(a, b)|^2
               + mu |A_v - A_v^default|^2,

S_f the patch after the G1 solve (linear in the control points and the anchors: the rows
``stacked``), L_f the target limit points, the other EPs' anchors at their defaults (the
eigen-polyhedron rule); mu = 1e-3 times the mean diagonal of the normal matrix (only to keep
the solve defined).  Coupled EPs (patches that read the anchors of several) take the damped
step of ``anchor_fairing`` (1 / k, k the largest number of fitted EPs on one of v's patches).
Everything is linear in the control points, so the fitted anchors are rows over them.

Our reading: the figure does not say which samples or which weights; these are the simplest
that see every coefficient of an irregular patch (25 samples per patch for 36 coefficients of
which the anchors move the inner ones through the G1 rows).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from patching.bernstein import bernstein
from patching.errors import NupatchError, UnsupportedError
from patching.mesh.control_mesh import ControlMesh
from patching.subdivision.catmark import subdivision_operator
from patching.subdivision.limit import limit_operator
from patching.topology.tables import Topology

__all__ = ["limit_targets", "fitted_anchors"]

MU = 1e-3
STEPS = 2


def limit_targets(mesh: ControlMesh, faces: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
    """(params (f, k, 2), targets (f k, n_points)): for each face of ``faces``, the parameters
    (s, t) of the k = (2^STEPS + 1)^2 level-STEPS vertices on it and their limit points as rows
    over the control points (``faces``: quads)."""
    topo0 = Topology(mesh)
    offsets = mesh.face_offsets
    # params[v] for the vertices of each face, level by level; start: the face's corners
    corner_st = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    owned = [{int(topo0.origin[offsets[f] + k]): corner_st[k] for k in range(4)} for f in faces.tolist()]
    # the child faces (of the current level) inside each original face
    inside = [[int(f)] for f in faces.tolist()]
    level, total = mesh, None
    for _ in range(STEPS):
        topo = Topology(level) if level is not mesh else topo0
        s, child = subdivision_operator(level, crease_method="uniform")
        nf, ne = level.n_faces, topo.n_edges
        off = level.face_offsets
        new_owned, new_inside = [], []
        for params, cells in zip(owned, inside):
            out, kids = {}, []
            for c in cells:
                hs = np.arange(off[c], off[c + 1])
                corners = [params[int(topo.origin[h])] for h in hs]
                out[c] = np.mean(corners, axis=0)  # face point
                for k, h in enumerate(hs.tolist()):
                    out[nf + int(topo.edge_of[h])] = 0.5 * (corners[k] + corners[(k + 1) % len(hs)])
                    out[nf + ne + int(topo.origin[h])] = corners[k]
                kids.extend(hs.tolist())  # child face of half-edge h (child_mesh's quads)
            new_owned.append(out)
            new_inside.append(kids)
        owned, inside = new_owned, new_inside
        total = s if total is None else (s @ total).tocsr()
        level = child
    # Zero-interval strips (clamped rims) give 0/0 in limit masks of vertices no sample uses.
    try:
        with np.errstate(divide="ignore", invalid="ignore"):
            limit = (limit_operator(level) @ total).tocsr()
    except NupatchError as exc:  # limit_operator's refusals (semi-sharp steps, face budget)
        raise UnsupportedError(
            f"anchors limit-fit: the subdivision limit surface is not available for this mesh ({exc})", mesh.name
        ) from exc
    ids = np.array([sorted(o) for o in owned], dtype=np.int64)  # (f, k)
    params = np.array([[o[i] for i in row] for o, row in zip(owned, ids.tolist())])
    return params, limit[ids.ravel()]


def fitted_anchors(
    mesh: ControlMesh,
    stacked: sp.csr_matrix,
    n_points: int,
    default: sp.csr_matrix,
    anchor_sets: list[np.ndarray],
    ring_faces: list[np.ndarray],
    patch_faces: np.ndarray,
    degrees: np.ndarray,
) -> sp.csr_matrix:
    """(n_anchors, n_points): anchors fitted to the limit surface (module docstring).

    stacked: all patch rows over [points | anchors]; default: the default anchors over the
    points; anchor_sets[e], ring_faces[e]: the anchor indices (among anchors) and the ring's
    faces of each EP; patch_faces, degrees: the face and degree of every patch in row order."""
    row_of_face = np.full(mesh.n_faces, -1, dtype=np.int64)
    row_of_face[patch_faces] = np.arange(patch_faces.size)
    first = np.concatenate([[0], np.cumsum((degrees + 1) ** 2)])
    wanted = np.unique(np.concatenate(ring_faces)) if ring_faces else np.zeros(0, np.int64)
    wanted = wanted[row_of_face[wanted] >= 0]
    if wanted.size == 0:
        return default.tocsr()
    params, targets = limit_targets(mesh, wanted)
    k = params.shape[1]
    sample_of = {int(f): i for i, f in enumerate(wanted.tolist())}
    anchor_part = stacked[:, n_points:].tocsc()
    point_part = stacked[:, :n_points].tocsr()
    # sampling rows: value at (s, t) of patch r = sum_ij B_i(s) B_j(t) row[first_r + i (d+1) + j]
    evaluation = []
    for f in wanted.tolist():
        r = int(row_of_face[f])
        d = int(degrees[r])
        bs = bernstein(d, params[sample_of[f], :, 0])
        bt = bernstein(d, params[sample_of[f], :, 1])
        w = (bs[:, :, None] * bt[:, None, :]).reshape(k, -1)
        cols = first[r] + np.arange((d + 1) ** 2)
        evaluation.append(sp.csr_matrix((w.ravel(), (np.repeat(np.arange(k), cols.size), np.tile(cols, k))), shape=(k, stacked.shape[0])))
    evaluation = sp.vstack(evaluation, format="csr")  # (f k, rows)
    sampled_points = (evaluation @ point_part).tocsr()
    sampled_anchors = (evaluation @ anchor_part).tocsc()
    touched = [np.unique(sampled_anchors[:, ids].tocoo().row // k) for ids in anchor_sets]
    sharing = np.zeros(wanted.size, dtype=np.int64)
    for t in touched:
        sharing[t] += 1
    out = default.tolil(copy=True)
    for ids, faces in zip(anchor_sets, ring_faces):
        local = np.array([sample_of[int(f)] for f in faces.tolist() if int(f) in sample_of], dtype=np.int64)
        rows = (k * local[:, None] + np.arange(k)).ravel()
        target = targets[rows].toarray()
        if not np.isfinite(target).all():  # a limit mask undefined on this ring: keep the defaults
            continue
        r_a = sampled_anchors[rows][:, ids].toarray()
        start = default[ids].toarray()
        rest = (sampled_points[rows] + sampled_anchors[rows] @ default).toarray() - r_a @ start
        h = r_a.T @ r_a
        mu = MU * float(np.mean(np.diag(h)))
        rhs = r_a.T @ (target - rest) + mu * start
        solved = np.linalg.solve(h + mu * np.eye(len(ids)), rhs)
        solved = start + (solved - start) / max(1, int(sharing[local].max()))
        solved[np.abs(solved) < 1e-15] = 0.0
        out[ids] = solved
    return out.tocsr()
