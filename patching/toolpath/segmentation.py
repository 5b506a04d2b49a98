"""Segmentation of the control mesh into regular pieces ([FSLYJ] sec. 4.3).

A piece is a rectangular grid of faces in one parametrisation: cell (i, j) holds one face with
a rotation r (the face's local side (k + r) mod 4 faces the piece's direction k; directions
0..3 = -v, +u, +v, -u, the patch sides of ``patching.surface``), grid neighbours are mesh
neighbours across the matching sides, so the patches join into one map of [0, nu] x [0, nv].

[FSLYJ] assigns every edge a weight measuring the complexity of the segmentation if it were
cut and solves a minimum spanning tree with Kruskal's algorithm, without formulas.  Our
reading, on the dual graph (faces, joined across shared non-sharp mesh edges):

* the *join weight* of a dual edge e between faces f, g is
  w(e) = 1 + 10 (1 - n_f . n_g) + [e ends at an EP] + [e ends at a sharp vertex]
  (n_f, n_g the two patches' unit normals at the middle of the shared side): high where the
  surface turns, at extraordinary points and at the ends of creases, i.e. where a cut is
  natural; the *cut weight* is c(e) = 1 / w(e) in (0, 1], what a cut there costs.  Sharp
  edges are not in the graph: always cut, at no cost.
* T = the minimum spanning tree (forest) of the dual graph under w, by
  ``scipy.sparse.csgraph.minimum_spanning_tree``; equally the maximum spanning tree under c
  (a spanning tree depends only on the order of the weights).  It keeps together the faces
  that are the most expensive to separate.
* T is cut into rectangles: Kruskal's order over T's edges (increasing w), an edge joining the
  pieces of its two faces only if their union is again a rectangle in one parametrisation;
  rejected edges are offered again until a pass adds none.  Without the constraint this
  rebuilds T; with it the result is a spanning forest F contained in T, every piece a subtree
  of T.  F is *not* a minimum spanning forest of any graph: which tree edges are cut depends
  on the pieces grown so far.
* A rectangle constraint on subtrees of one tree is strong (two strips beside each other may
  be joined in T only through a third piece), so a second greedy pass joins whole pieces across
  any dual edges, into rectangles only, the pair of smallest join weight first (the mean w of
  the dual edges it takes in over their number: long shared sides first; with single-edge joins
  only, equal weights on a plain grid leave strips of mismatched lengths that never merge).
  After this pass pieces need no longer be subtrees of T.
* The same greedy pass alone, from single faces, is the plain constrained Kruskal on the
  piece graph (``method="greedy"``).  ``segment`` runs both and keeps the segmentation of
  lower total cut weight C = sum of c(e) over the dual edges between different pieces (ties:
  the tree's).  On the shipped models the tree wins on l_bracket (C = 44.5 against 48.5),
  ties on clamped_grid and torus_nonuniform (one piece each) and loses on square_frame
  (41.5 against 22.0) and machined_bracket (9.5 against 3.17), so C is never above the greedy's
  by construction, and the tree's pass is what makes it lower where it does.

Neither is optimal (the rectangle partition of least cut weight is a combinatorial problem we
do not solve): the tree orders and constrains the first joins only.  scipy's
``minimum_spanning_tree`` has no way to express the rectangle constraint itself, so the
union-find over pieces is written here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree

from ..mesh import ControlMesh
from ..topology import Topology
from ..topology.features import sharp_edges

__all__ = ["DIRECTIONS", "METHODS", "Piece", "cut_weight", "dual_edges", "segment", "spanning_tree"]

#: grid offset of piece directions 0..3 (-v, +u, +v, -u).
DIRECTIONS = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]])


@dataclass(frozen=True)
class Piece:
    """faces: (nu, nv) int64 mesh face per cell; rotation: (nu, nv) int64 r per cell."""

    faces: np.ndarray
    rotation: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return self.faces.shape


def _turn(x: int, y: int, k: int) -> tuple[int, int]:
    """Grid vector in a frame rotated by k quarter turns (direction d becomes d - k)."""
    for _ in range(k % 4):
        x, y = y, -x
    return x, y


def dual_edges(
    mesh: ControlMesh, faces: np.ndarray, side_normals: np.ndarray, topology: Topology | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The dual graph over the given faces (module docstring): (f, kf, g, kg, w), one row per
    shared non-sharp mesh edge, f's local side kf meeting g's local side kg, join weight w."""
    topo = topology if topology is not None else Topology(mesh)
    faces = np.asarray(faces, dtype=np.int64)
    member = np.zeros(topo.n_faces, dtype=bool)
    member[faces] = True
    offsets = mesh.face_offsets
    sharp = sharp_edges(topo)
    ep = np.zeros(topo.n_vertices, dtype=bool)
    ep[topo.extraordinary] = True
    sharp_vertex = np.bincount(topo.edges[sharp].ravel(), minlength=topo.n_vertices) > 0
    # Dual edges: interior half-edges h < twin(h) between two member faces, not sharp.
    h = np.flatnonzero(topo.twin >= 0)
    h = h[h < topo.twin[h]]
    f, g = topo.face[h], topo.face[topo.twin[h]]
    keep = member[f] & member[g] & ~sharp[topo.edge_of[h]] & (f != g)
    h, f, g = h[keep], f[keep], g[keep]
    kf = h - offsets[f]
    kg = topo.twin[h] - offsets[g]
    cos = np.einsum("nc,nc->n", side_normals[f, kf], side_normals[g, kg])
    ends = topo.edges[topo.edge_of[h]]
    weight = 1.0 + 10.0 * (1.0 - cos) + ep[ends].sum(axis=1) + sharp_vertex[ends].sum(axis=1)
    return f, kf, g, kg, weight


def spanning_tree(n_faces: int, f: np.ndarray, g: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(E,) bool, the dual edges in the minimum spanning forest under ``weight`` (scipy's
    Kruskal; of several dual edges between one pair of faces only the lightest can be in it)."""
    if f.size == 0:
        return np.zeros(0, dtype=bool)
    a, b = np.minimum(f, g), np.maximum(f, g)
    order = np.lexsort((weight, b, a))
    first = order[np.r_[True, (np.diff(a[order]) != 0) | (np.diff(b[order]) != 0)]]
    graph = coo_matrix((weight[first], (a[first], b[first])), shape=(n_faces, n_faces)).tocsr()
    tree = minimum_spanning_tree(graph).tocoo()
    in_tree = set(zip(tree.row.tolist(), tree.col.tolist()))
    chosen = np.zeros(f.size, dtype=bool)
    chosen[[e for e in first.tolist() if (int(a[e]), int(b[e])) in in_tree]] = True
    return chosen


def cut_weight(pieces: list[Piece], f: np.ndarray, kf: np.ndarray, g: np.ndarray, weight: np.ndarray) -> float:
    """Total cut weight C: the sum of 1 / w over the dual edges not joined inside a piece (a
    dual edge is joined when g is the grid neighbour of f across f's side kf in one piece;
    an edge between faces of one piece that are not neighbours there, such as where a piece
    closes around a torus, is a cut)."""
    where = {}
    for k, p in enumerate(pieces):
        for (i, j), face in np.ndenumerate(p.faces):
            where[int(face)] = (k, i, j, int(p.rotation[i, j]))
    joined = np.zeros(len(f), dtype=bool)
    for e, (a, ka, b) in enumerate(zip(f.tolist(), kf.tolist(), g.tolist())):
        pa, ia, ja, ra = where[a]
        pb, ib, jb, _ = where[b]
        d = DIRECTIONS[(ka - ra) % 4]
        joined[e] = pa == pb and (ib - ia, jb - ja) == (int(d[0]), int(d[1]))
    return float(np.sum(1.0 / weight[~joined]))


METHODS = ("best", "tree", "greedy")


def segment(
    mesh: ControlMesh,
    faces: np.ndarray,
    side_normals: np.ndarray,
    topology: Topology | None = None,
    method: str = "best",
) -> list[Piece]:
    """Cut the given faces (quads with patches) into rectangular pieces (module docstring).

    faces: (k,) face ids to cover; side_normals: (n_faces, 4, 3) unit normal of each face's
    patch at the middle of its sides (rows of faces not covered are ignored).  method: "tree"
    (the minimum spanning tree cut into rectangles, then greedy joins), "greedy" (greedy joins
    from single faces), "best" (of those two the one of lower total cut weight, ties to
    "tree").  Every face in ``faces`` ends in exactly one piece."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, not {method!r}")
    topo = topology if topology is not None else Topology(mesh)
    faces = np.asarray(faces, dtype=np.int64)
    f, kf, g, kg, weight = dual_edges(mesh, faces, side_normals, topo)
    results = []
    if method in ("best", "tree"):
        chosen = spanning_tree(topo.n_faces, f, g, weight)
        results.append(_grow(faces, f, kf, g, kg, weight, np.flatnonzero(chosen)[np.argsort(weight[chosen], kind="stable")]))
    if method in ("best", "greedy"):
        results.append(_grow(faces, f, kf, g, kg, weight, np.zeros(0, dtype=np.int64)))
    if len(results) == 1:
        return results[0]
    costs = [cut_weight(p, f, kf, g, weight) for p in results]
    return results[int(np.argmin(np.round(costs, 9)))]


def _grow(faces, f, kf, g, kg, weight, tree_edges) -> list[Piece]:
    """Pieces from single faces: first Kruskal's order over ``tree_edges`` (a tree edge joins
    the pieces of its faces when their union is a rectangle; offered again until a pass adds
    none), then greedy joins of whole pieces, the smallest join weight (mean w of the dual
    edges taken in over their number: long shared sides first) first, into rectangles only."""
    neighbour = {}  # (face, local side) -> (face, local side)
    for a, ka, b, kb in zip(f.tolist(), kf.tolist(), g.tolist(), kg.tolist()):
        neighbour[(a, ka)] = (b, kb)
        neighbour[(b, kb)] = (a, ka)

    owner = {int(x): int(x) for x in faces}  # face -> piece key
    cells = {int(x): {(0, 0): (int(x), 0)} for x in faces}  # piece key -> {(i, j): (face, r)}
    where = {int(x): (0, 0, 0) for x in faces}  # face -> (i, j, r) in its piece
    next_key = int(faces.max()) + 1 if faces.size else 0

    def union_of(a: int, ka: int, b: int, kb: int):
        """The cells of piece(a) joined with piece(b) across a's side ka, or None."""
        pa, pb = owner[a], owner[b]
        ia, ja, ra = where[a]
        d = (ka - ra) % 4
        target = (ia + int(DIRECTIONS[d, 0]), ja + int(DIRECTIONS[d, 1]))
        rb_new = (kb - d - 2) % 4
        ib, jb, rb = where[b]
        delta = (rb_new - rb) % 4
        union = dict(cells[pa])
        for (i, j), (face, r) in cells[pb].items():
            x, y = _turn(i - ib, j - jb, delta)
            key = (x + target[0], y + target[1])
            if key in union:
                return None
            union[key] = (face, (r + delta) % 4)
        keys = np.array(list(union))
        lo, hi = keys.min(axis=0), keys.max(axis=0)
        if int(np.prod(hi - lo + 1)) != len(union):
            return None
        # Grid neighbours must be mesh neighbours across the matching sides.
        for (i, j), (face, r) in union.items():
            for d2 in (1, 2):
                other = union.get((i + int(DIRECTIONS[d2, 0]), j + int(DIRECTIONS[d2, 1])))
                if other is None:
                    continue
                if neighbour.get((face, (d2 + r) % 4)) != (other[0], (d2 + 2 + other[1]) % 4):
                    return None
        return {(i - int(lo[0]), j - int(lo[1])): v for (i, j), v in union.items()}

    def join(pa: int, pb: int, union: dict) -> None:
        nonlocal next_key
        del cells[pa], cells[pb]
        key = next_key
        next_key += 1
        cells[key] = union
        for (i, j), (face, r) in union.items():
            owner[face] = key
            where[face] = (i, j, r)

    edges = list(zip(f.tolist(), kf.tolist(), g.tolist(), kg.tolist()))
    changed = len(tree_edges) > 0
    while changed:
        changed = False
        for e in tree_edges.tolist():
            a, ka, b, kb = edges[e]
            if owner[a] != owner[b]:
                union = union_of(a, ka, b, kb)
                if union is not None:
                    join(owner[a], owner[b], union)
                    changed = True

    failed: set[tuple[int, int]] = set()
    while True:
        shared: dict[tuple[int, int], list[int]] = {}
        for e, (a, _, b, _) in enumerate(edges):
            pa, pb = owner[a], owner[b]
            if pa != pb:
                shared.setdefault((min(pa, pb), max(pa, pb)), []).append(e)
        # rounded: equal joins up to round-off go by piece key, reproducibly
        ranked = sorted((round(float(weight[e].mean()) / len(e), 9), key) for key, e in shared.items() if key not in failed)
        for _, key in ranked:
            a, ka, b, kb = edges[shared[key][0]]
            union = union_of(a, ka, b, kb)
            if union is not None:
                join(owner[a], owner[b], union)
                break
            failed.add(key)
        else:
            break

    pieces = []
    for key in sorted(cells, key=lambda p: min(v[0] for v in cells[p].values())):
        grid = cells[key]
        keys = np.array(list(grid))
        nu, nv = keys.max(axis=0) + 1
        fa = np.zeros((nu, nv), dtype=np.int64)
        ro = np.zeros((nu, nv), dtype=np.int64)
        for (i, j), (face, r) in grid.items():
            fa[i, j], ro[i, j] = face, r
        pieces.append(Piece(fa, ro))
    return pieces
