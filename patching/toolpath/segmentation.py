"""Segmentation of the control mesh into regular pieces ([FSLYJ] sec. 4.3).

A piece is a rectangular grid of faces in one parametrisation: cell (i, j) holds one face with
a rotation r (the face's local side (k + r) mod 4 faces the piece's direction k; directions
0..3 = -v, +u, +v, -u, the patch sides of ``patching.surface``), grid neighbours are mesh
neighbours across the matching sides, so the patches join into one map of [0, nu] x [0, nv].

[FSLYJ] assigns every edge a weight measuring how complex the segmentation would be if it
were cut and solves a minimum spanning tree with Kruskal's algorithm.  We do it on the dual
graph (faces, joined across mesh edges) with the *join* weight

    w(e) = 1 + 10 (1 - n_f . n_g) + [e ends at an EP] + [e ends at a sharp vertex],

(n_f, n_g the two patches' unit normals at the middle of the shared side), sharp edges never
joined: Kruskal adds dual edges in increasing w, keeping an edge only when it joins two pieces
whose union is again a rectangle in one parametrisation.  The kept edges form a spanning
forest (each tree a piece), the rejected ones are the cuts, which therefore fall where the
surface turns, at extraordinary points and along creases.  Because the rectangle test depends
on the pieces grown so far, rejected edges are offered again in the same order until a pass
adds none.  scipy's ``minimum_spanning_tree`` has no way to express the rectangle constraint
(it would return one tree over the whole face graph), so the union-find is written here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..topology.features import sharp_edges
from ..mesh import ControlMesh
from ..topology import Topology

__all__ = ["DIRECTIONS", "Piece", "segment"]

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


def segment(
    mesh: ControlMesh, faces: np.ndarray, side_normals: np.ndarray, topology: Topology | None = None
) -> list[Piece]:
    """Cut the given faces (quads with patches) into rectangular pieces.

    faces: (k,) face ids to cover; side_normals: (n_faces, 4, 3) unit normal of each face's
    patch at the middle of its sides (rows of faces not covered are ignored).
    Every face in ``faces`` ends in exactly one piece."""
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

    # Dual edges grouped by the pair of pieces they join; a join's weight is the mean weight
    # of the dual edges it takes in divided by their number (long shared sides first).
    edge_list = list(zip(f.tolist(), kf.tolist(), g.tolist(), kg.tolist(), weight.tolist()))
    cache: dict[tuple[int, int], tuple[float, dict] | None] = {}

    def candidate(pa: int, pb: int):
        key = (min(pa, pb), max(pa, pb))
        if key not in cache:
            crossing = [e for e in edge_list if {owner[e[0]], owner[e[2]]} == {pa, pb}]
            best = None
            for a, ka, b, kb, _ in crossing[:1]:
                if owner[a] != pa:
                    a, ka, b, kb = b, kb, a, ka
                union = union_of(a, ka, b, kb)
                if union is not None:
                    w = np.array([e[4] for e in crossing])
                    best = (float(w.mean()) / len(w), union)
            cache[key] = best
        return cache[key]

    while True:
        pairs = {(min(owner[a], owner[b]), max(owner[a], owner[b])) for a, _, b, _, _ in edge_list if owner[a] != owner[b]}
        best = None
        for pa, pb in sorted(pairs):
            c = candidate(pa, pb)
            if c is not None and (best is None or c[0] < best[0] - 1e-12):
                best = (c[0], pa, pb, c[1])
        if best is None:
            break
        _, pa, pb, union = best
        del cells[pa], cells[pb]
        key = next_key
        next_key += 1
        cells[key] = union
        for (i, j), (face, r) in union.items():
            owner[face] = key
            where[face] = (i, j, r)

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

