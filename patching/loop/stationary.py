"""Limit positions and normals at the vertices of a stationary level, for Loop and
Catmull-Clark alike: the eigen-analysis of each vertex's own 1-ring subdivision matrix.

At a stationary level (no semi-sharp tag left: every rule stays the same from step to step)
the 1-ring of a vertex v, ``R = [v, E_0 .. E_{m-1}]`` (Loop) or ``[v, E_i .., F_i ..]``
(Catmull-Clark: spoke ends, then the quads' far corners), is mapped by one step onto the
1-ring of v's child with a fixed matrix ``B = S[child ring, ring]``, the rows of the operator
itself (so every rule, including darts and crease sides, is the one the geometry uses).
With ``B``'s left eigenvectors ``l_j B = lambda_j l_j``:

* limit point: ``l_0 . R`` with ``lambda_0 = 1``, ``sum l_0 = 1``;
* tangent plane: spanned by ``l_a . R`` and ``l_b . R`` for the two largest subdominant
  eigenvalues (a double one at smooth vertices, the Fourier pair); the normal is their cross
  product, oriented as the faces of the ring.

Crease and corner vertices have one normal per *region* (the faces between two sharp edges,
[ZBK] sec. 3.4); each region's block (v, its bounding sharp spokes, the spokes and far corners
inside) is closed under the rules, and its own eigenvectors give that side's normal.  On a
crease side of k faces the interior mode has ``lambda = 3/8 + cos(pi/k)/4`` (Loop), which
exceeds the crease curve's 1/2 for k >= 4: then the side's normal is the cross product of the
curve tangent and that mode, not of [OSD]'s sine-formula tangent.  At darts the sharp spoke's
crease rule changes the whole matrix (the centre weight of the limit at valence 6 is 0.516,
not Loop's 1/2).

Where the two largest subdominant eigenvalues do not single out a plane (a tie of more than
two: a corner sector of three Loop faces, where the interior mode and both curve tangents
have 1/2; a Catmull-Clark crease side of one face, where curve curvature and the face mode
tie at 1/4), the normal is the sum of the ring's facet normals taken at the limit points of
the ring (``approximate`` marks these regions).

Plain vertices (interior, smooth, regular faces, no tagged neighbour) are grouped by valence
and share one analysis (Loop: [OSD]'s closed-form limit mask and the cos/sin tangent masks,
which are the exact eigenvectors there); the others are analysed one by one, cached by the
block's values.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .cache import topology_of
from .rules import CORNER, DART, SMOOTH, loop_limit_edge_weight, vertex_rule

__all__ = ["StationaryMasks", "corner_regions", "stationary_masks", "evaluate_normals", "level_rules", "concat_masks", "regions_of", "plain_vertices"]

_TIE = 1e-8


def level_rules(mesh, topo) -> tuple[np.ndarray, np.ndarray]:
    """(sharp (e,) bool, rule (v,) int8) of a level as [OSD] tags it: crease tags > 0 and
    boundary edges sharp; corner tags and (interpolateboundary 1) topological corners sharp."""
    sharp = (topo.edge_sharpness > 0) | topo.edge_is_boundary
    vs = np.zeros(topo.n_vertices)
    if mesh.corners:
        vs[np.fromiter(mesh.corners.keys(), np.int64)] = np.fromiter(mesh.corners.values(), np.float64)
    if mesh.interpolate_boundary == 1:
        n_faces_at = np.bincount(topo.origin, minlength=topo.n_vertices)
        vs[topo.vertex_is_boundary & (n_faces_at == 1) & (topo.valence == 2)] = np.inf
    count = np.bincount(topo.edges[sharp].ravel(), minlength=topo.n_vertices)
    return sharp, vertex_rule(vs, count)


def corner_regions(topo, sharp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Regions of face corners around each vertex, separated by sharp edges ([ZBK] sec. 3.4,
    Fig. 6b): (label (H,) region id of every corner = half-edge, region_vertex (r,)).

    Regions are numbered by their smallest corner (as ``connected_components`` of the corner
    graph numbers them); the graph is only built at vertices with a sharp edge, the corners of
    every other vertex forming one region."""
    H = topo.origin.size
    h = np.arange(H)
    at_sharp = np.zeros(topo.n_vertices, bool)
    at_sharp[topo.edges[sharp].ravel()] = True
    hs = np.flatnonzero(at_sharp[topo.origin])
    provisional = topo.origin.astype(np.int64).copy()
    if hs.size:
        local = np.full(H, -1, np.int64)
        local[hs] = np.arange(hs.size)
        nb = topo.twin[topo.prev[hs]]  # the corner across edge prev(h), around origin(h)
        ok = (nb >= 0) & ~sharp[topo.edge_of[topo.prev[hs]]]
        g = sp.coo_matrix((np.ones(int(ok.sum())), (local[hs[ok]], local[nb[ok]])), shape=(hs.size, hs.size))
        _, lab = connected_components(g, directed=False)
        provisional[hs] = topo.n_vertices + lab
    smallest = np.empty(topo.n_vertices + hs.size, np.int64)
    smallest[provisional[::-1]] = h[::-1]
    used = np.zeros(smallest.size, bool)
    used[provisional] = True
    ids = np.flatnonzero(used)
    rank = np.empty(smallest.size, np.int64)
    rank[ids[np.argsort(smallest[ids], kind="stable")]] = np.arange(ids.size)
    label = rank[provisional]
    rv = np.zeros(ids.size, np.int64)
    rv[label] = topo.origin
    return label, rv


_REGIONS: OrderedDict[int, tuple] = OrderedDict()


def regions_of(mesh) -> tuple[np.ndarray, np.ndarray]:
    """``corner_regions`` of the mesh's own sharp edges (``level_rules``), cached by object
    identity like ``cache.topology_of``: (label (H,), region_vertex (r,))."""
    key = id(mesh)
    hit = _REGIONS.get(key)
    if hit is not None and hit[0] is mesh:
        _REGIONS.move_to_end(key)
        return hit[1]
    topo = topology_of(mesh)
    out = corner_regions(topo, level_rules(mesh, topo)[0])
    _REGIONS[key] = (mesh, out)
    while len(_REGIONS) > 8:
        _REGIONS.popitem(last=False)
    return out


@dataclass
class StationaryMasks:
    """Linear masks over the level's vertices.  position (v, n) CSR: limit points.
    Per region r (``region_of_corner`` (H,), ``region_vertex`` (r,)): ``tangent_a``,
    ``tangent_b`` (r, n) CSR, normal ~ (a P) x (b P); ``facet_a``, ``facet_b`` (q, n) with
    ``facet_region`` (q,): facet pairs whose summed cross products orient the normal (one
    facet a region, at the level's points) and are the normal where ``approximate`` (every
    facet of the region, at the ring's limit points)."""

    position: sp.csr_matrix
    region_of_corner: np.ndarray
    region_vertex: np.ndarray
    tangent_a: sp.csr_matrix
    tangent_b: sp.csr_matrix
    facet_a: sp.csr_matrix
    facet_b: sp.csr_matrix
    facet_region: np.ndarray
    approximate: np.ndarray

    def compose(self, total: sp.spmatrix) -> "StationaryMasks":
        """The masks over coarser points: every matrix times ``total`` (level = total @ coarse)."""
        t = sp.csr_matrix(total)
        return StationaryMasks(
            (self.position @ t).tocsr(), self.region_of_corner, self.region_vertex,
            (self.tangent_a @ t).tocsr(), (self.tangent_b @ t).tocsr(),
            (self.facet_a @ t).tocsr(), (self.facet_b @ t).tocsr(), self.facet_region, self.approximate,
        )


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (numpy's ``cross`` is several times slower)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def evaluate_normals(masks: StationaryMasks, points: np.ndarray) -> np.ndarray:
    """(r, 3) unit limit normal of every region (nonlinear: a cross product of linear masks)."""
    n = cross(masks.tangent_a @ points, masks.tangent_b @ points)
    c = cross(masks.facet_a @ points, masks.facet_b @ points)
    nr = masks.region_vertex.size
    o = np.stack([np.bincount(masks.facet_region, weights=c[:, i], minlength=nr) for i in range(3)], axis=1)
    sign = np.where(np.einsum("ij,ij->i", n, o) < 0, -1.0, 1.0)
    n = n * sign[:, None]
    n = np.where(masks.approximate[:, None], o, n)
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


_CACHE: dict[bytes, tuple] = {}


def _analyse(block: np.ndarray, curve: tuple = (), kind: str = "ring"):
    """(limit weights (m,), tangent pair (2, m) or None) from the left eigenvectors of block.

    kind "ring" (smooth or dart vertex, every point interior): the two largest subdominant
    eigenvalues (a double one or two single ones).  "side" (a crease side; ``curve`` the local
    indices of v and the two crease ends): the crease curve's tangent (the eigenvalue-1/2
    eigenvector supported on the curve points alone) and the dominant mode with support inside
    the side (a side without inner points: the curve's 1/4 mode).  "corner": the two curve
    tangents (eigenvalue 1/2, e_E - e_V along each bounding crease).  None where that choice is
    not unique (a tie of interior modes)."""
    key = np.round(block, 13).tobytes() + bytes(f"{block.shape}{curve}{kind}", "ascii")
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    w, vl = np.linalg.eig(block.T)
    order = np.argsort(-np.abs(w), kind="stable")
    w, vl = w[order], vl[:, order]
    lim = np.real(vl[:, 0])
    lim = lim / lim.sum()
    aw = np.abs(w[1:])
    rest = np.real(vl[:, 1:])
    pair = None
    if kind == "ring":
        if aw.size >= 2:
            g1 = np.flatnonzero(np.abs(aw - aw[0]) < _TIE)
            if g1.size == 2:
                pair = rest[:, g1].T
                # a complex pair, or a double real eigenvalue that eig returned as a conjugate
                # pair (imaginary parts of the values below _TIE, of the vectors not: a
                # Catmull-Clark dart of valence 4 in some ring orders): the real and imaginary
                # parts of one vector span the invariant plane (the real parts of the two are
                # the same vector, a zero normal)
                if np.abs(np.imag(vl[:, 1 + g1])).max() > _TIE:
                    pair = np.stack([np.real(vl[:, 1 + g1[0]]), np.imag(vl[:, 1 + g1[0]])])
            elif g1.size == 1 and (aw.size == 2 or abs(aw[1] - aw[2]) >= _TIE) and aw[1] > _TIE:
                pair = rest[:, [0, 1]].T
    else:
        m = block.shape[0]
        cv = np.array(curve, np.int64)
        inner = np.setdiff1d(np.arange(m), cv)
        # the crease curve's own modes: left eigenvectors supported on v and the two ends
        cw, cl = np.linalg.eig(block[np.ix_(cv, cv)].T)
        cw, cl = np.real(cw), np.real(cl)

        def pad(x):
            out = np.zeros(m)
            out[cv] = x
            return out

        halves = np.flatnonzero(np.abs(cw - 0.5) < _TIE)
        if kind == "corner":
            if halves.size == 2:
                pair = np.stack([pad(cl[:, halves[0]]), pad(cl[:, halves[1]])])
        elif halves.size == 1:
            t = pad(cl[:, halves[0]])
            other = None
            if inner.size:
                lam = np.linalg.eigvals(block[np.ix_(inner, inner)])
                top = np.abs(lam).max()
                if np.count_nonzero(np.abs(np.abs(lam) - top) < _TIE) == 1:
                    g = np.flatnonzero(np.abs(aw - top) < _TIE)
                    cand = rest[:, g] - np.outer(t, t @ rest[:, g]) / (t @ t)
                    j = int(np.argmax(np.linalg.norm(cand, axis=0))) if g.size else -1
                    if j >= 0 and np.linalg.norm(cand[:, j]) > 1e-9 * np.linalg.norm(rest[:, g[j]]):
                        other = rest[:, g[j]]
            else:
                q = np.flatnonzero(np.abs(cw - 0.25) < _TIE)
                if q.size == 1:
                    other = pad(cl[:, q[0]])
            if other is not None:
                pair = np.stack([t, other])
    out = (lim, pair)
    _CACHE[key] = out
    return out


def _block(S: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Dense ``S[rows][:, cols]``, read from the CSR arrays directly."""
    if np.unique(cols).size != cols.size:
        return S[rows][:, cols].toarray()
    starts, ends = S.indptr[rows], S.indptr[rows + 1]
    cnt = ends - starts
    idx = np.repeat(starts - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(cnt.sum())
    c = S.indices[idx]
    r = np.repeat(np.arange(rows.size), cnt)
    order = np.argsort(cols)
    j = np.searchsorted(cols[order], c)
    j = np.minimum(j, cols.size - 1)
    hit = cols[order][j] == c
    out = np.zeros((rows.size, cols.size))
    np.add.at(out, (r[hit], order[j[hit]]), S.data[idx[hit]])
    return out


class _Rows:
    def __init__(self):
        self.r, self.c, self.v = [], [], []

    def add(self, r, c, v):
        r, c, v = np.broadcast_arrays(np.asarray(r, np.int64), np.asarray(c, np.int64), np.asarray(v, np.float64))
        self.r.append(r.ravel())
        self.c.append(c.ravel())
        self.v.append(v.ravel())

    def matrix(self, shape):
        if not self.r:
            return sp.csr_matrix(shape)
        m = sp.csr_matrix((np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))), shape=shape)
        m.sum_duplicates()
        return m


def plain_vertices(mesh, topo, scheme: str) -> np.ndarray:
    """(v,) bool: interior smooth vertices with regular faces and no sharp edge (Catmull-Clark:
    and no tagged vertex on their faces), whose normal is oriented by the ring's order."""
    nv = topo.n_vertices
    sharp, rule = level_rules(mesh, topo)
    regular = 3 if scheme == "loop" else 4
    bad_face = np.zeros(nv, bool)
    bad_face[topo.origin[np.diff(mesh.face_offsets)[topo.face] != regular]] = True
    plain = ~topo.vertex_is_boundary & (rule == SMOOTH) & ~bad_face
    plain &= np.bincount(topo.edges[sharp].ravel(), minlength=nv) == 0
    if scheme != "loop":
        tagged_e = rule[topo.origin] != SMOOTH
        nb = np.zeros(nv, bool)
        nb[topo.dest[tagged_e]] = True
        nb[topo.origin[tagged_e[topo.next[topo.next]]]] = True
        plain &= ~nb
    return plain


def _flat_ring(k: int) -> np.ndarray:
    """(2k + 1, 3) a flat regular Catmull-Clark 1-ring in the fans' order: v, the spoke ends
    counter-clockwise seen from the faces' side, then the far corners between them."""
    t = 2 * np.pi * np.arange(k) / k
    e = np.stack([np.cos(t), np.sin(t), 0 * t], 1)
    f = np.sqrt(2) * np.stack([np.cos(t + np.pi / k), np.sin(t + np.pi / k), 0 * t], 1)
    return np.vstack([np.zeros((1, 3)), e, f])


def stationary_masks(mesh, topo, S, scheme: str, targets: np.ndarray | None = None) -> StationaryMasks:
    """Limit and normal masks at every vertex of a stationary level (module docstring).

    mesh, topo: the level and its Topology; S: the operator of its next step (rows in the
    child numbering of ``scheme``: "loop" (``patching.loop.refine``) or "catmark"
    (``patching.subdivision``: faces, edges, vertices)), or a callable that, given the
    vertices whose 1-ring blocks are read, returns an operator exact on those rows
    (``patching.loop.local.local_rows``).  Faces must be triangles (loop) or quads (catmark).
    targets: the vertices whose normals are wanted (default all); limit points are computed
    for them and their 1-rings (the facets are taken at limit points)."""
    nv, ne, nf = topo.n_vertices, topo.n_edges, topo.n_faces
    loop = scheme == "loop"
    sharp, rule = level_rules(mesh, topo)
    if topo is topology_of(mesh):
        label, region_vertex = regions_of(mesh)
    else:
        label, region_vertex = corner_regions(topo, sharp)
    nr = region_vertex.size
    if loop:
        vrow, erow = (lambda v: v), (lambda e: nv + e)
    else:
        vrow, erow = (lambda v: nf + ne + v), (lambda e: nf + e)
    pos, ta, tb, fa, fb = _Rows(), _Rows(), _Rows(), _Rows(), _Rows()
    freg: list[np.ndarray] = []
    approx = np.zeros(nr, bool)
    used = topo.vertex_is_used.copy()
    want = np.ones(nv, bool)
    if targets is not None:
        want[:] = False
        want[np.asarray(targets, np.int64)] = True
        need = want.copy()
        h = np.flatnonzero(want[topo.origin])
        need[topo.dest[h]] = True
        need[topo.origin[topo.prev[h]]] = True
        if not loop:
            need[topo.dest[topo.next[h]]] = True
        used &= need
    iso = np.flatnonzero(~topo.vertex_is_used & want)
    pos.add(iso, iso, 1.0)
    regular = 3 if loop else 4
    fsize = np.diff(mesh.face_offsets)
    bad_face = np.zeros(nv, bool)
    bad_face[topo.origin[fsize[topo.face] != regular]] = True
    nb_tagged = np.zeros(nv, bool)
    tagged_e = rule[topo.origin] != SMOOTH
    nb_tagged[topo.dest[tagged_e]] = True
    if not loop:
        nb_tagged[topo.origin[tagged_e[topo.next[topo.next]]]] = True
    # plain vertices (the fans' test below, per vertex): their blocks are shared by valence
    plain_v = plain_vertices(mesh, topo, scheme)
    if callable(S):
        read = np.flatnonzero(used & ~plain_v)
        if not loop:
            pv = np.flatnonzero(used & plain_v)
            _, rep = np.unique(topo.valence[pv], return_index=True)
            read = np.union1d(read, pv[rep])
        S = S(read)
    S = sp.csr_matrix(S)
    n_facets = 0
    for ring, boundary in topo.fans(np.flatnonzero(used)):
        g, k = ring.shape
        v = topo.origin[ring[:, 0]]
        last = topo.prev[ring[:, -1]]
        if boundary:
            spokes_e = np.concatenate([topo.edge_of[ring], topo.edge_of[last][:, None]], axis=1)
            ends = np.concatenate([topo.dest[ring], topo.origin[last][:, None]], axis=1)
        else:
            spokes_e = topo.edge_of[ring]
            ends = topo.dest[ring]
        m = ends.shape[1]
        if loop:
            cols = np.concatenate([v[:, None], ends], axis=1)
            rows = np.concatenate([vrow(v)[:, None], erow(spokes_e)], axis=1)
        else:
            far = topo.dest[topo.next[ring]]
            cols = np.concatenate([v[:, None], ends, far], axis=1)
            rows = np.concatenate([vrow(v)[:, None], erow(spokes_e), topo.face[ring]], axis=1)
        reg = label[ring[:, 0]]
        wanted = want[v]
        spoke_sharp = sharp[spokes_e]
        plain = (not boundary) & (rule[v] == SMOOTH) & ~bad_face[v] & ~spoke_sharp.any(axis=1)
        if not loop:
            plain &= ~nb_tagged[v]
        # facet pairs (orientation, approximate normals): per face i of the ring; plain
        # vertices' tangents are oriented by the ring's order (below), their first facet is
        # kept only where the pair is not unique (Catmull-Clark, ``approximate``)
        # (all faces of the group at once, rows in the order face i, pair, vertex)
        w_rest = np.flatnonzero(wanted & ~plain)
        w_first = w_rest if loop else np.flatnonzero(wanted)
        fw, fp, fq, fi = [], [], [], []
        for i in range(k):
            j = (i + 1) % m
            pairs = [(1 + i, 1 + j)] if loop else [(1 + i, 1 + m + i), (1 + m + i, 1 + j)]
            wv = w_rest if i else w_first
            for p, q in pairs:
                fw.append(wv)
                fp.append(np.full(wv.size, p))
                fq.append(np.full(wv.size, q))
                fi.append(np.full(wv.size, i))
        fw_a, fp_a, fq_a = np.concatenate(fw), np.concatenate(fp), np.concatenate(fq)
        idx = np.arange(fw_a.size) + n_facets
        n_facets += fw_a.size
        both, sign = np.concatenate([idx, idx]), np.repeat([1.0, -1.0], fw_a.size)
        fa.add(both, np.concatenate([cols[fw_a, fp_a], v[fw_a]]), sign)
        fb.add(both, np.concatenate([cols[fw_a, fq_a], v[fw_a]]), sign)
        freg.append(label[ring[fw_a, np.concatenate(fi)]])
        grp = np.flatnonzero(plain)
        if grp.size and loop:
            n = float(k)
            ew = float(loop_limit_edge_weight(n))
            pos.add(v[grp, None], cols[grp], np.concatenate([[1 - n * ew], np.full(k, ew)])[None])
            th = 2 * np.pi * np.arange(k) / k
            gw = grp[wanted[grp]]
            # oriented by the ring's order, not by a facet: the fans run so that (sum cos E)
            # x (sum sin E) points to the faces' side (on a flat regular ring, the faces'
            # normal; checked on every loop_* shape against the facet-oriented normals);
            # a facet flips it where the level's ring folds over (a crease just decayed)
            ta.add(reg[gw, None], cols[gw, 1:], np.cos(th)[None])
            tb.add(reg[gw, None], cols[gw, 1:], np.sin(th)[None])
        elif grp.size:
            r0 = int(grp[0])
            block = _block(S, rows[r0], cols[r0])
            lim, pair = _analyse(block)
            pos.add(v[grp, None], cols[grp], lim[None])
            gw = grp[wanted[grp]]
            if pair is not None:
                # oriented by the ring's order: on a flat regular ring the pair's normal must
                # point to the faces' side (+z), as Loop's cos/sin pair does
                R = _flat_ring(k)
                if cross((pair[0] @ R)[None], (pair[1] @ R)[None])[0, 2] < 0:
                    pair = np.stack([pair[0], -pair[1]])
            if pair is None:
                approx[reg[gw]] = True
            else:
                ta.add(reg[gw, None], cols[gw], pair[0][None])
                tb.add(reg[gw, None], cols[gw], pair[1][None])
        for r0 in np.flatnonzero(~plain).tolist():
            block = _block(S, rows[r0], cols[r0])
            vv = int(v[r0])
            ss = np.flatnonzero(spoke_sharp[r0])
            if not boundary and (rule[vv] in (SMOOTH, DART) or ss.size < 2):
                sectors = [np.arange(m + 1)]  # one region, the whole ring
                sector_cols = [np.arange(cols.shape[1])]
            else:
                sectors, sector_cols = [], []
                if boundary:
                    cuts = sorted(set(ss.tolist()) | {0, m - 1})
                    bounds = list(zip(cuts[:-1], cuts[1:]))
                else:
                    cuts = ss.tolist()
                    bounds = [(cuts[i], cuts[i + 1] if i + 1 < len(cuts) else cuts[0] + m) for i in range(len(cuts))]
                for a, b in bounds:
                    sp_idx = np.arange(a, b + 1) % m
                    idx = [0] + (1 + sp_idx).tolist()
                    if not loop:
                        idx += (1 + m + (np.arange(a, b) % m)).tolist()
                    sectors.append(np.arange(a, b))
                    sector_cols.append(np.array(idx))
            first = True
            whole = len(sectors) == 1 and sector_cols[0].size == cols.shape[1] and not boundary and ss.size < 2
            kind = "ring" if whole else ("corner" if rule[vv] == CORNER else "side")
            for faces_i, idx in zip(sectors, sector_cols):
                sub = block[np.ix_(idx, idx)]
                nsp = faces_i.size + 1  # spokes of the sector: its faces + 1
                lim, pair = _analyse(sub, (0, 1, nsp), kind)
                c = cols[r0, idx]
                if first:
                    pos.add(np.full(c.size, vv), c, lim)
                    first = False
                if not wanted[r0]:
                    break
                face_local = int(faces_i[0]) % k if faces_i.size else 0
                rr = int(label[ring[r0, face_local]])
                if pair is None:
                    approx[rr] = True
                else:
                    ta.add(np.full(c.size, rr), c, pair[0])
                    tb.add(np.full(c.size, rr), c, pair[1])
    freg_a = np.concatenate(freg) if freg else np.zeros(0, np.int64)
    # one facet per region orients its normal; approximate regions keep all (their normal)
    keep = np.zeros(freg_a.size, bool)
    _, first_idx = np.unique(freg_a, return_index=True)
    keep[first_idx] = True
    keep &= ~plain_v[region_vertex[freg_a]]  # oriented by the ring's order
    keep |= approx[freg_a]
    sel = np.flatnonzero(keep)
    freg_a = freg_a[sel]
    q = freg_a.size
    P = pos.matrix((nv, nv))
    # facets of approximate regions at the limit points of the ring (the difference rows
    # times the limit masks); the others only orient a normal, at the level's points
    return StationaryMasks(
        P, label, region_vertex, ta.matrix((nr, nv)), tb.matrix((nr, nv)),
        _at_limit(fa.matrix((keep.size, nv))[sel], P, approx[freg_a]),
        _at_limit(fb.matrix((keep.size, nv))[sel], P, approx[freg_a]), freg_a, approx,
    )


def _at_limit(F: sp.csr_matrix, P: sp.csr_matrix, rows: np.ndarray) -> sp.csr_matrix:
    """Rows ``rows`` of F replaced by F @ P (limit points), the others kept."""
    if not rows.any():
        return F
    idx = np.flatnonzero(rows)
    keep = sp.diags((~rows).astype(np.float64))
    put = sp.csr_matrix((np.ones(idx.size), (idx, np.arange(idx.size))), shape=(rows.size, idx.size))
    return (keep @ F + put @ (F[idx] @ P)).tocsr()


def select_regions(masks: StationaryMasks, regions: np.ndarray) -> StationaryMasks:
    """The masks of the regions ``regions`` only (renumbered 0..len - 1); position unchanged;
    ``region_of_corner`` is dropped (-1) since the corners of the level are not the caller's."""
    regions = np.asarray(regions, np.int64)
    new = np.full(masks.region_vertex.size, -1, np.int64)
    new[regions] = np.arange(regions.size)
    keep = np.flatnonzero(new[masks.facet_region] >= 0)
    return StationaryMasks(
        masks.position, np.full(0, -1, np.int64), masks.region_vertex[regions],
        masks.tangent_a[regions], masks.tangent_b[regions], masks.facet_a[keep], masks.facet_b[keep],
        new[masks.facet_region[keep]], masks.approximate[regions],
    )


def concat_masks(parts: list, position: sp.csr_matrix) -> StationaryMasks:
    """The regions of several StationaryMasks over the same points, one after the other
    (``position`` given; ``region_of_corner`` dropped)."""
    n = position.shape[1]
    if not parts:
        empty = sp.csr_matrix((0, n))
        return StationaryMasks(position, np.zeros(0, np.int64), np.zeros(0, np.int64), empty, empty, empty, empty,
                               np.zeros(0, np.int64), np.zeros(0, bool))
    offsets = np.cumsum([0] + [p.region_vertex.size for p in parts[:-1]])
    return StationaryMasks(
        position, np.full(0, -1, np.int64), np.concatenate([p.region_vertex for p in parts]),
        sp.vstack([p.tangent_a for p in parts]).tocsr(), sp.vstack([p.tangent_b for p in parts]).tocsr(),
        sp.vstack([p.facet_a for p in parts]).tocsr(), sp.vstack([p.facet_b for p in parts]).tocsr(),
        np.concatenate([p.facet_region + o for p, o in zip(parts, offsets)]),
        np.concatenate([p.approximate for p in parts]),
    )
