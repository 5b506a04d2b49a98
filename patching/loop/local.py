"""Limit masks with local refinement: only the neighbourhood of semi-sharp features is refined,
until those features have decayed, before the stationary masks apply ([OSD]'s ``Limit()``
treats semi-sharp features as sharp; here they are refined away, as [KSD] sec. 3 and [ZBK]
sec. 3.2 let them decay).  For Loop and Catmull-Clark alike.

Why a neighbourhood is enough.  One step maps the 1-ring R of a vertex v onto the 1-ring of
v's child with a matrix B read from the rows of S (``stationary``).  Those rows (v's vertex
point, its spokes' edge points, for Catmull-Clark the face points of its faces) depend only
on the tags of v, of its spokes and of the 1-ring's vertices (Chaikin creasing reads every
semi-sharp edge at an end, the [TLC] rules the rule of the far end), so they are exact when
the faces touching any vertex of v's 1-ring are present (the *2-ring faces* of v).  Refining
those faces alone gives, around v's child, the children of v's own faces with exact points and
tags, and these hold the child's 2-ring faces: the work per vertex does not grow from level to
level.

Readiness.  B stays the same at every later step once no vertex of v's 1-ring has a
semi-sharp incident edge and none is a semi-sharp corner (then every rule it reads is final):
v's limit point and tangents are read at that level (a ring that lists a vertex twice, faces
back to back, waits a step: its children's rings are distinct), ``l . R_j = l . R_k`` for any later level
k since ``l B = lambda l``.  Vertices whose normal is oriented by a facet of the level (all
but ``stationary.plain_vertices``, whose tangents are oriented by the ring's order: a ring that
folds over at a coarse level would flip them) and the regions whose normal is ``approximate`` (the sum of facet
normals at the ring's limit points, which depends on the level) are only taken at the level
where the whole mesh would be stationary (``decay``, the global path's level), so the result
equals the global path's (``refine="global"``: the whole mesh refined ``decay`` times) up to
rounding.  Checked in tests/test_loop_local.py on small meshes to 1e-12.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..mesh import ControlMesh
from ..topology import Topology
from .cache import topology_of
from .rules import INFINITE
from .stationary import (
    concat_masks,
    plain_vertices,
    regions_of,
    select_regions,
    stationary_masks,
)

__all__ = ["LocalScheme", "local_limit", "local_rows", "ring_faces", "submesh"]


class LocalScheme:
    """What the local refinement needs of a scheme: one step (S, child) and where a vertex and a
    face corner go in the child numbering."""

    def __init__(self, name: str, step: Callable[[ControlMesh], tuple[sp.csr_matrix, ControlMesh]]):
        self.name = name
        self.step = step

    def child_vertex(self, topo: Topology, v: np.ndarray) -> np.ndarray:
        if self.name == "loop":
            return v
        return topo.n_faces + topo.n_edges + v

    def child_corner(self, topo: Topology, h: np.ndarray) -> np.ndarray:
        """Corner h (origin[h] of face[h]) -> the child's corner at the same vertex."""
        if self.name == "loop":
            f = topo.face[h]
            return 12 * f + 3 * (h - 3 * f)  # child face 4 f + local, its corner 0
        return 4 * h  # child face h, its corner 0

    def child_row(self, topo: Topology, sub: Topology, s2g: np.ndarray, fmap: np.ndarray,
                  gedge: np.ndarray) -> np.ndarray:
        """(rows of the submesh's S,) -> the rows of the same points in the parent's child
        numbering (``fmap`` submesh face -> face, ``gedge`` submesh edge -> edge)."""
        if self.name == "loop":
            return np.concatenate([s2g, topo.n_vertices + gedge])
        return np.concatenate([fmap, topo.n_faces + gedge, topo.n_faces + topo.n_edges + s2g])


def ring_faces(topo: Topology, vertices: np.ndarray) -> np.ndarray:
    """(f,) bool: the faces touching any vertex of a face at ``vertices`` (their 2-ring faces)."""
    vm = np.zeros(topo.n_vertices, bool)
    vm[vertices] = True
    fm = np.zeros(topo.n_faces, bool)
    fm[topo.face[vm[topo.origin]]] = True
    vm[topo.origin[fm[topo.face]]] = True
    fm[topo.face[vm[topo.origin]]] = True
    return fm


def submesh(mesh: ControlMesh, topo: Topology, faces: np.ndarray):
    """The faces ``faces`` (bool mask or ids) as a mesh of their own, with their tags:
    (mesh, s2g (n,) its vertices' ids in ``mesh``, fmap (f,) its faces', hmap (H,) its
    corners' (half-edges')).  Faces are added around every vertex whose faces in the
    selection would form more than one fan, so that the submesh is manifold."""
    fm = np.zeros(mesh.n_faces, bool)
    fm[faces] = True
    while True:
        h = np.flatnonzero(fm[topo.face])
        nb = topo.twin[topo.prev[h]]
        start = (nb < 0) | ~fm[topo.face[np.maximum(nb, 0)]]
        fans = np.bincount(topo.origin[h[start]], minlength=mesh.n_vertices)
        split = fans > 1
        if not split.any():
            break
        fm[topo.face[split[topo.origin]]] = True
    f = np.flatnonzero(fm)
    fo = mesh.face_offsets
    sizes = fo[f + 1] - fo[f]
    off = np.concatenate([[0], np.cumsum(sizes)])
    hmap = np.repeat(fo[f], sizes) + np.arange(off[-1]) - np.repeat(off[:-1], sizes)
    gv = mesh.face_vertices[hmap]
    s2g, local = np.unique(gv, return_inverse=True)
    g2s = np.full(mesh.n_vertices, -1, np.int64)
    g2s[s2g] = np.arange(s2g.size)
    es = topo.edge_sharpness
    e = np.unique(topo.edge_of[hmap])
    e = e[es[e] > 0]
    a, b = g2s[topo.edges[e, 0]], g2s[topo.edges[e, 1]]
    creases = {(int(x), int(y)): float(s) for x, y, s in zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist(),
                                                                es[e].tolist())}
    corners = {int(g2s[v]): float(s) for v, s in mesh.corners.items() if g2s[v] >= 0}
    holes = frozenset()
    if mesh.holes:
        fl = np.full(mesh.n_faces, -1, np.int64)
        fl[f] = np.arange(f.size)
        hl = fl[np.fromiter(mesh.holes, np.int64)]
        holes = frozenset(int(x) for x in hl[hl >= 0].tolist())
    sub = ControlMesh(
        vertices=np.ascontiguousarray(mesh.vertices[s2g]), face_vertices=local.astype(np.int64).ravel(),
        face_offsets=off.astype(np.int64), intervals={}, creases=creases, corners=corners, holes=holes,
        interpolate_boundary=mesh.interpolate_boundary, name=mesh.name, crease_method=mesh.crease_method,
    )
    return sub, s2g, f, hmap


def _edge_ids(topo: Topology, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Ids of the edges a-b (Topology numbers edges by the key ``lo * n + hi``, sorted)."""
    n = topo.n_vertices
    keys = topo.edges[:, 0] * n + topo.edges[:, 1]
    return np.searchsorted(keys, np.minimum(a, b) * n + np.maximum(a, b))


def local_rows(mesh: ControlMesh, topo: Topology, scheme: LocalScheme, vertices: np.ndarray) -> sp.csr_matrix:
    """S of one step of ``mesh`` in its own child numbering, exact on the rows of the 1-ring
    blocks of ``vertices`` (built on their 2-ring faces only; the other rows are empty)."""
    nchild = topo.n_vertices + topo.n_edges + (topo.n_faces if scheme.name != "loop" else 0)
    if np.asarray(vertices).size == 0:
        return sp.csr_matrix((nchild, topo.n_vertices))
    sub, s2g, fmap, _ = submesh(mesh, topo, ring_faces(topo, vertices))
    st = topology_of(sub)
    S, _ = scheme.step(sub)
    gedge = _edge_ids(topo, s2g[st.edges[:, 0]], s2g[st.edges[:, 1]])
    rows = scheme.child_row(topo, st, s2g, fmap, gedge)
    M = S.tocoo()
    return sp.csr_matrix((M.data, (rows[M.row], s2g[M.col])), shape=(nchild, topo.n_vertices))


def _unsettled(mesh: ControlMesh, topo: Topology, scheme: str) -> np.ndarray:
    """(v,) bool: a vertex of the vertex's 1-ring faces has a semi-sharp edge or corner or
    (Catmull-Clark) touches a face that is not a quad: its 1-ring matrix may still change."""
    es = topo.edge_sharpness
    semi = np.zeros(topo.n_vertices, bool)
    semi[topo.edges[(es > 0) & (es < INFINITE)].ravel()] = True
    if scheme != "loop":
        semi[topo.origin[np.diff(mesh.face_offsets)[topo.face] != 4]] = True
    for v, s in mesh.corners.items():
        if 0 < s < INFINITE:
            semi[v] = True
    if not semi.any():
        return semi
    fm = np.zeros(topo.n_faces, bool)
    fm[topo.face[semi[topo.origin]]] = True
    near = np.zeros(topo.n_vertices, bool)
    near[topo.origin[fm[topo.face]]] = True
    return near


def _repeated_ring(topo: Topology, scheme: str, vertices: np.ndarray) -> np.ndarray:
    """(len(vertices),) bool: the vertex's 1-ring lists a vertex twice (faces back to back,
    a tiny torus): its block is not a 1-ring matrix yet (the children's rings are distinct)."""
    n = topo.n_vertices
    vm = np.zeros(n, bool)
    vm[vertices] = True
    h = np.flatnonzero(vm[topo.origin])
    v = topo.origin[h]
    parts = [topo.dest[h], topo.origin[topo.prev[h]]] + ([topo.dest[topo.next[h]]] if scheme != "loop" else [])
    keys = np.unique(np.concatenate([v * n + x for x in parts]))
    distinct = np.bincount(keys // n, minlength=n)
    expected = topo.valence + (np.bincount(topo.origin, minlength=n) if scheme != "loop" else 0)
    return (distinct < expected)[vertices]


def _rows_of(mesh, topo, scheme):
    return lambda vertices: local_rows(mesh, topo, scheme, vertices)


def local_limit(mesh: ControlMesh, scheme: LocalScheme, decay: int):
    """Limit masks of every vertex of ``mesh`` (module docstring), refining locally up to
    ``decay`` steps (the level at which no semi-sharp tag is left anywhere).

    Returns (position (v, v) CSR over the mesh's points, masks: StationaryMasks over them,
    index (r0,) the masks' region of every region of ``mesh``, label0, rv0)."""
    topo0 = topology_of(mesh)
    label0, rv0 = regions_of(mesh)
    nv0 = mesh.n_vertices
    first = np.zeros(rv0.size, np.int64)
    first[label0[::-1]] = np.arange(label0.size)[::-1]
    cur, topo = mesh, topo0
    T = None  # cur's points over the mesh's (None: the identity)
    tv = np.arange(nv0)  # the targets' ids in cur
    to = np.arange(nv0)  # ... and in mesh
    rc = first.copy()  # the first corner of every region of a target, in cur
    ro = np.arange(rv0.size)  # ... its region in mesh
    pos_rows, pos_ids, pieces = [], [], []
    n_masks = 0
    index = np.full(rv0.size, -1, np.int64)
    for level in range(decay + 1):
        final = level == decay
        if final:
            ready = np.ones(tv.size, bool)
        else:
            ready = ~_unsettled(cur, topo, scheme.name)[tv]
            ready[ready] = ~_repeated_ring(topo, scheme.name, tv[ready])
            # normals oriented by a facet of the level (feature vertices) wait for the final
            # level too: a ring that folds over at a coarse level would flip them
            ready &= plain_vertices(cur, topo, scheme.name)[tv] | ~topo.vertex_is_used[tv]
        if ready.any():
            masks = stationary_masks(cur, topo, _rows_of(cur, topo, scheme), scheme.name, targets=tv[ready])
            if not final and masks.approximate.any():
                late = np.zeros(cur.n_vertices, bool)
                late[masks.region_vertex[masks.approximate]] = True
                ready &= ~late[tv]
            rv_ready = np.zeros(cur.n_vertices, bool)
            rv_ready[tv[ready]] = True
            rsel = rv_ready[topo.origin[rc]]
            if ready.any():
                regions_k = masks.region_of_corner[rc[rsel]]
                uniq, inv = np.unique(regions_k, return_inverse=True)
                if level == 0 and ready.all() and uniq.size == masks.region_vertex.size:
                    return masks.position, masks, inv, label0, rv0  # nothing refined: as they are
                sub = select_regions(masks, uniq)
                pos = masks.position[tv[ready]]
                if T is not None:
                    sub = sub.compose(T)
                    pos = pos @ T
                pos_rows.append(sp.csr_matrix(pos))
                pos_ids.append(to[ready])
                pieces.append(sub)
                index[ro[rsel]] = n_masks + inv
                n_masks += uniq.size
            tv, to = tv[~ready], to[~ready]
            rc, ro = rc[~rsel], ro[~rsel]
        if not tv.size or final:
            break
        sub_mesh, s2g, _, hmap = submesh(cur, topo, ring_faces(topo, tv))
        g2s = np.full(cur.n_vertices, -1, np.int64)
        g2s[s2g] = np.arange(s2g.size)
        h2s = np.full(topo.origin.size, -1, np.int64)
        h2s[hmap] = np.arange(hmap.size)
        st = topology_of(sub_mesh)
        S, child = scheme.step(sub_mesh)
        Tq = sp.csr_matrix((np.ones(s2g.size), (np.arange(s2g.size), s2g)), shape=(s2g.size, cur.n_vertices))
        T = (S @ (Tq if T is None else Tq @ T)).tocsr()
        tv = scheme.child_vertex(st, g2s[tv])
        rc = scheme.child_corner(st, h2s[rc])
        cur, topo = child, topology_of(child)
    ids = np.concatenate(pos_ids)
    order = np.empty(nv0, np.int64)
    order[ids] = np.arange(ids.size)
    P = sp.vstack(pos_rows).tocsr()[order].tocsr()
    return P, concat_masks(pieces, P), index, label0, rv0
