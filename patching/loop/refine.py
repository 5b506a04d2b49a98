"""One step of Loop subdivision as a sparse operator, with [OSD]'s creases, corners, semi-sharp
features and boundary rules (masks in ``rules``).

``loop_operator(mesh)`` returns ``S`` (scipy.sparse CSR; new points = ``S @ old``), built from
topology and tags only, and the refined ControlMesh with its tags.

Child numbering (vertex points keep their ids, so a control vertex is vertex ``v`` at every
level; [OSD]'s refiner orders the vertices from parent vertices first as well)::

    vertex point of vertex v    v
    edge point of edge e        n_vertices + e        (Topology's edge numbering)

Child faces: triangle f = (v0, v1, v2) with edges e_i = (v_i, v_{i+1}) becomes child faces
``4 f + i`` = (v_i, E(e_i), E(e_{i-1})) for i = 0, 1, 2 and ``4 f + 3`` = (E(e_0), E(e_1),
E(e_2)), same orientation.  Child edges: the two halves of every parent edge carry its child
sharpness (``rules.child_edge_sharpness``; infinite stays), the three edges inside a face are
smooth.  Corner sharpness decrements by one.  Holes: the children of a hole are holes.

Tags as [OSD]'s ``Far::TopologyRefinerFactory`` applies them: sharpness >= 10 is infinite;
every boundary edge is infinitely sharp in all interpolateboundary modes; mode 1
(edge-and-corner, as [OSD]'s ``shape_utils`` maps the OBJ value) makes a boundary vertex of one
face infinitely sharp; mode 0 (none) tags as holes the faces around every boundary vertex
with a boundary edge not tagged infinitely sharp (done on the input mesh only: the refined
mesh's boundary edges are written as infinitely sharp crease tags, so that reading it back
does not tag the next ring of faces).  Uniform knots only: non-uniform interval tags raise a
KnotError, non-triangle faces an UnsupportedError, each naming the face or edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..errors import KnotError, UnsupportedError
from ..mesh import ControlMesh
from ..topology import Topology
from .cache import remember, topology_of
from .rules import (
    CORNER,
    CREASE,
    DART,
    fractional_weight,
    loop_beta,
    vertex_rule,
)
from patching.rules.crease import CREASE_METHODS, INFINITE, child_edge_sharpness, crease_method_of, decrement

__all__ = ["LoopLevel", "child_topology", "loop_operator", "loop_subdivide", "CREASE_METHODS", "MAX_LOOP_FACES"]

#: Largest mesh ``loop_subdivide`` makes (about 1 kB of memory per triangle on the way).
MAX_LOOP_FACES = 4_000_000


def check_loop_mesh(mesh: ControlMesh) -> None:
    """Refuse what Loop subdivision does not take here, in one line naming the place."""
    sizes = mesh.face_sizes
    bad = np.flatnonzero(sizes != 3)
    if bad.size:
        f = int(bad[0])
        raise UnsupportedError(
            f"--scheme loop takes triangles only: face {f} has {int(sizes[f])} vertices",
            mesh.locations.get(("face", f), f"face {f}"),
        )


def check_uniform(mesh: ControlMesh, n_edges: int) -> None:
    """Uniform knots: no interval tag other than 1, or one value on every edge (a uniform
    scaling); otherwise a KnotError naming an edge."""
    values = sorted({float(d) for d in mesh.intervals.values()})
    if not values or values == [1.0] or (len(values) == 1 and len(mesh.intervals) == n_edges):
        return
    other = values[0] if values[0] != 1.0 else values[-1]
    (a, b) = next(k for k, v in mesh.intervals.items() if float(v) == other)
    raise KnotError(
        f"--scheme loop takes uniform knots only: edge {a}-{b} has interval {other:g}",
        mesh.locations.get(("interval", (a, b)), f"edge {a}-{b}"),
    )


@dataclass
class LoopLevel:
    """Topology and tags of one level, as flat arrays (read-only after construction)."""

    mesh: ControlMesh
    topo: Topology
    es: np.ndarray  # (e,) edge sharpness, infinite as inf, boundary edges inf
    vs: np.ndarray  # (v,) vertex sharpness, inf where infinitely sharp
    child_es: np.ndarray  # (e, 2) child half sharpness at edges[:, k]
    holes: np.ndarray  # (f,) bool
    crease_method: str = "uniform"  # the one used for child_es, carried by the child mesh

    @classmethod
    def of(cls, mesh: ControlMesh, crease_method: str | None = None) -> "LoopLevel":
        crease_method = crease_method_of(mesh, crease_method)
        if crease_method not in CREASE_METHODS:
            raise UnsupportedError(f"crease method must be one of {', '.join(CREASE_METHODS)}, got '{crease_method}'")
        check_loop_mesh(mesh)
        t = topology_of(mesh)
        check_uniform(mesh, t.n_edges)
        es = t.edge_sharpness.copy()
        explicit_inf = es >= INFINITE
        es[explicit_inf] = np.inf
        es[t.edge_is_boundary] = np.inf
        vs = np.zeros(t.n_vertices)
        if mesh.corners:
            idx = np.fromiter(mesh.corners.keys(), np.int64)
            vs[idx] = np.fromiter(mesh.corners.values(), np.float64)
        vs[vs >= INFINITE] = np.inf
        n_faces_at = np.bincount(t.origin, minlength=t.n_vertices)
        if mesh.interpolate_boundary == 1:
            vs[t.vertex_is_boundary & (n_faces_at == 1) & (t.valence == 2)] = np.inf
        holes = np.zeros(t.n_faces, bool)
        if mesh.holes:
            holes[np.fromiter(mesh.holes, np.int64)] = True
        if mesh.interpolate_boundary == 0:
            soft = t.edge_is_boundary & ~explicit_inf
            bad_v = np.zeros(t.n_vertices, bool)
            bad_v[t.edges[soft].ravel()] = True
            holes[t.face[bad_v[t.origin]]] = True
        child = child_edge_sharpness(np.where(np.isinf(es), INFINITE, es), t.edges, t.n_vertices, crease_method)
        child[child >= INFINITE] = np.inf
        return cls(mesh, t, es, vs, child, holes, crease_method)

    @cached_property
    def sharp_count(self) -> np.ndarray:
        return np.bincount(self.topo.edges[self.es > 0].ravel(), minlength=self.topo.n_vertices)

    @cached_property
    def rule(self) -> np.ndarray:
        """(v,) parent vertex rule ([OSD] ``DetermineVertexVertexRule``)."""
        return vertex_rule(self.vs, self.sharp_count)

    @cached_property
    def child_rule(self) -> np.ndarray:
        """(v,) rule of each vertex's child vertex (child vertex sharpness, child halves)."""
        t = self.topo
        cnt = np.zeros(t.n_vertices, np.int64)
        for k in (0, 1):
            np.add.at(cnt, t.edges[self.child_es[:, k] > 0, k], 1)
        return vertex_rule(decrement(self.vs), cnt)

    @cached_property
    def opposite(self) -> tuple[np.ndarray, np.ndarray]:
        """(e,) the vertices opposite each edge in its two triangles (-1 on a boundary)."""
        t = self.topo
        h0 = t.edge_halfedge
        c = t.origin[t.prev[h0]]
        h1 = t.twin[h0]
        d = np.where(h1 >= 0, t.origin[t.prev[np.maximum(h1, 0)]], -1)
        return c, d


def _edge_rows(L: LoopLevel):
    """Rows of the edge points: (rows, cols, vals)."""
    t = L.topo
    ne, nv = t.n_edges, t.n_vertices
    a, b = t.edges[:, 0], t.edges[:, 1]
    c, d = L.opposite
    sharp = L.es > 0
    child_crease = (L.child_es > 0).all(axis=1)
    # weight of the crease mask: 0 smooth, 1 sharp with a crease child, else s (unclamped)
    p = np.where(sharp, np.where(child_crease, 1.0, L.es), 0.0)
    q = 1.0 - p
    e = np.arange(ne)
    rows = [nv + e, nv + e]
    cols = [a, b]
    vals = [0.5 * p + 0.375 * q, 0.5 * p + 0.375 * q]
    inner = d >= 0
    rows += [nv + e[q != 0], nv + e[inner & (q != 0)]]
    cols += [c[q != 0], d[inner & (q != 0)]]
    vals += [0.125 * q[q != 0], 0.125 * q[inner & (q != 0)]]
    return rows, cols, vals


def _vertex_rows(L: LoopLevel):
    """Rows of the vertex points (masks and blends in ``rules``)."""
    t = L.topo
    nv = t.n_vertices
    a, b = t.edges[:, 0], t.edges[:, 1]
    prule, crule = L.rule, L.child_rule
    n = t.valence.astype(np.float64)
    beta = np.where(n > 0, loop_beta(np.maximum(n, 1)), 0.0)
    # transitions per vertex for the fractional weight: edges sharp now, smooth at this end next
    tsum, tcnt = np.zeros(nv), np.zeros(nv)
    for k, end in enumerate((a, b)):
        turn = (L.es > 0) & (L.child_es[:, k] <= 0)
        np.add.at(tsum, end[turn], L.es[turn])
        np.add.at(tcnt, end[turn], 1.0)
    w = fractional_weight(L.vs, decrement(L.vs), tsum, tcnt)
    smoothish = prule <= DART
    # coefficients of the four masks per vertex
    c_smooth = np.where(smoothish, 1.0, 0.0)
    c_pcrease = np.zeros(nv)
    c_corner = np.zeros(nv)
    c_ccrease = np.zeros(nv)
    same = prule == crule
    pw = np.where(same, 1.0, w)
    cw = 1.0 - pw
    hard = ~smoothish
    c_pcrease[hard & (prule == CREASE)] = pw[hard & (prule == CREASE)]
    c_corner[hard & (prule == CORNER)] = pw[hard & (prule == CORNER)]
    blend = hard & ~same
    c_smooth[blend & (crule <= DART)] += cw[blend & (crule <= DART)]
    c_ccrease[blend & (crule == CREASE)] += cw[blend & (crule == CREASE)]
    c_corner[blend & (crule == CORNER)] += cw[blend & (crule == CORNER)]
    self_w = c_smooth * (1.0 - n * beta) + 0.75 * (c_pcrease + c_ccrease) + c_corner
    rows, cols, vals = [np.arange(nv)], [np.arange(nv)], [self_w]
    for k, (here, there) in enumerate(((a, b), (b, a))):
        wt = c_smooth[here] * beta[here]
        wt = wt + 0.125 * c_pcrease[here] * (L.es > 0)
        wt = wt + 0.125 * c_ccrease[here] * (L.child_es[:, k] > 0)
        keep = wt != 0
        rows.append(here[keep])
        cols.append(there[keep])
        vals.append(wt[keep])
    return rows, cols, vals


def _operator(L: LoopLevel) -> sp.csr_matrix:
    t = L.topo
    r1, c1, v1 = _vertex_rows(L)
    r2, c2, v2 = _edge_rows(L)
    r = np.concatenate(r1 + r2)
    c = np.concatenate(c1 + c2)
    v = np.concatenate(v1 + v2)
    s = sp.csr_matrix((v, (r, c)), shape=(t.n_vertices + t.n_edges, t.n_vertices))
    s.sum_duplicates()
    s.eliminate_zeros()
    return s


def _child_mesh(L: LoopLevel, points: np.ndarray) -> ControlMesh:
    t = L.topo
    nv = t.n_vertices
    fo = L.mesh.face_offsets
    h0 = fo[:-1]
    h = np.stack([h0, h0 + 1, h0 + 2], axis=1)  # (f, 3) half-edges (v_i -> v_{i+1})
    v = t.origin[h]
    E = nv + t.edge_of[h]
    faces = np.empty((t.n_faces, 4, 3), np.int64)
    for i in range(3):
        faces[:, i] = np.stack([v[:, i], E[:, i], E[:, (i - 1) % 3]], axis=1)
    faces[:, 3] = E
    creases: dict[tuple[int, int], float] = {}
    ends = t.edges
    for k in (0, 1):
        keep = np.flatnonzero((L.child_es[:, k] > 0) & (~t.edge_is_boundary | (L.mesh.interpolate_boundary == 0)))
        s = np.where(np.isinf(L.child_es[keep, k]), np.maximum(t.edge_sharpness[keep], INFINITE), L.child_es[keep, k])
        for e, val in zip(keep.tolist(), s.tolist()):
            a, b = int(ends[e, k]), nv + e
            creases[(min(a, b), max(a, b))] = float(val)
    corners = {}
    for vid, s in L.mesh.corners.items():
        d = float(decrement(s))
        if d > 0:
            corners[int(vid)] = d
    holes = np.flatnonzero(np.repeat(L.holes, 4))
    return ControlMesh(
        vertices=np.ascontiguousarray(points, dtype=np.float64),
        face_vertices=faces.reshape(-1),
        face_offsets=np.arange(0, 12 * t.n_faces + 1, 3, dtype=np.int64),
        intervals={},
        creases=creases,
        corners=corners,
        holes=frozenset(int(x) for x in holes.tolist()),
        interpolate_boundary=L.mesh.interpolate_boundary,
        name=L.mesh.name,
        crease_method=L.crease_method,
    )


def child_topology(t: Topology, child: ControlMesh) -> Topology:
    """The Topology of a Loop step's child mesh, from the parent's tables (the child numbering
    of the module docstring), equal to ``Topology(child)`` array for array (edges numbered by
    the key ``lo * n + hi`` as it numbers them, ``edge_halfedge`` the smallest half-edge)
    without its sorting of every half-edge and its manifold check (a child of a manifold mesh
    is manifold).  Child half-edge ``12 f + 3 i + j`` is corner j of child face ``4 f + i``."""
    nv, ne, nf = t.n_vertices, t.n_edges, t.n_faces
    nvc, H = nv + ne, 12 * nf
    c = Topology.__new__(Topology)
    c.mesh = child
    c.n_faces, c.n_vertices = 4 * nf, nvc
    c.origin = child.face_vertices.astype(np.int64)
    h = np.arange(H, dtype=np.int64)
    c.face = np.repeat(np.arange(4 * nf, dtype=np.int64), 3)
    c.next = h + np.tile(np.array([1, 1, -2], np.int64), 4 * nf)
    c.prev = h + np.tile(np.array([2, -1, -1], np.int64), 4 * nf)
    c.dest = c.origin[c.next]
    # candidate edges: half k of parent edge e (2 e + k), then inner edge i of face f
    pe = t.edge_of.reshape(nf, 3)  # e_i of face f
    pv = t.origin.reshape(nf, 3)  # v_i
    e_prev = pe[:, [2, 0, 1]]  # e_{i-1}
    half_keys = (t.edges * nvc + (nv + np.arange(ne))[:, None]).ravel()
    lo, hi = np.minimum(pe, e_prev), np.maximum(pe, e_prev)
    inner_keys = ((nv + lo) * nvc + nv + hi).ravel()
    keys = np.concatenate([half_keys, inner_keys])
    order = np.argsort(keys, kind="stable")
    rank = np.empty(keys.size, np.int64)
    rank[order] = np.arange(keys.size)
    sk = keys[order]
    c.edges = np.stack([sk // nvc, sk % nvc], axis=1)
    c.n_edges = int(keys.size)
    k_at = (t.edges[pe, 1] == pv).astype(np.int64)  # which half of e_i is at v_i
    k_prev = (t.edges[e_prev, 1] == pv).astype(np.int64)  # ... of e_{i-1} at v_i
    eo = np.empty((nf, 4, 3), np.int64)
    eo[:, :3, 0] = 2 * pe + k_at
    eo[:, :3, 1] = 2 * ne + 3 * np.arange(nf)[:, None] + np.arange(3)
    eo[:, :3, 2] = 2 * e_prev + k_prev
    eo[:, 3, :] = eo[:, [1, 2, 0], 1]  # E_j -> E_{j+1}: inner edge i = j + 1
    c.edge_of = rank[eo.ravel()]
    twin = np.full(H, -1, np.int64)
    f = np.arange(nf)[:, None]
    i = np.arange(3)[None, :]
    corner = 12 * f + 3 * i
    centre = 12 * f + 9 + (i - 1) % 3
    twin[(corner + 1).ravel()] = centre.ravel()
    twin[centre.ravel()] = (corner + 1).ravel()
    pt = t.twin.reshape(nf, 3)  # twin of parent half-edge 3 f + i
    ok = pt >= 0
    fp, ip = pt // 3, pt % 3
    twin[corner[ok]] = (12 * fp + 3 * ((ip + 1) % 3) + 2)[ok]
    ptp = pt[:, [2, 0, 1]]  # twin of 3 f + (i - 1)
    okp = ptp >= 0
    twin[(corner + 2)[okp]] = (12 * (ptp // 3) + 3 * (ptp % 3))[okp]
    c.twin = twin
    eh = np.empty(c.n_edges, np.int64)
    eh[c.edge_of[::-1]] = h[::-1]
    c.edge_halfedge = eh
    c.edge_is_boundary = twin[eh] < 0
    return c


def loop_operator(mesh: ControlMesh, crease_method: str | None = None) -> tuple[sp.csr_matrix, ControlMesh]:
    """One Loop step: (S, refined mesh).

    S: (n_vertices + n_edges, n_vertices) CSR float64, rows sum to 1, from topology and tags
    only (child numbering in the module docstring); the refined mesh's positions are
    ``S @ mesh.vertices`` and it carries the child tags.  crease_method: "uniform" (sharpness
    drops by 1) or "chaikin" ([OSD] ``CREASE_CHAIKIN``); None (default): the mesh's
    ``crease_method`` (OBJ tag ``t creasemethod``).  Raises UnsupportedError (non-triangle
    face), KnotError (non-uniform intervals), MeshError (non-manifold input).
    """
    L = LoopLevel.of(mesh, crease_method)
    s = _operator(L)
    child = _child_mesh(L, s @ mesh.vertices)
    remember(child, lambda: child_topology(L.topo, child))
    return s, child


def level_operator(mesh: ControlMesh, crease_method: str | None = None) -> sp.csr_matrix:
    """S of ``loop_operator`` without building the refined mesh."""
    return _operator(LoopLevel.of(mesh, crease_method))


def loop_subdivide(mesh: ControlMesh, steps: int = 1, crease_method: str | None = None) -> ControlMesh:
    """``steps`` Loop steps: the refined mesh with its tags (crease_method as ``loop_operator``)."""
    crease_method = crease_method_of(mesh, crease_method)
    if steps < 0:
        raise UnsupportedError(f"number of subdivision steps must be >= 0, got {steps}")
    faces = mesh.n_faces * 4**steps
    if faces > MAX_LOOP_FACES:
        raise UnsupportedError(
            f"{steps} Loop steps of {mesh.n_faces} faces make {faces:.3g} faces, more than {MAX_LOOP_FACES:,}",
            mesh.name,
        )
    if steps == 0:
        LoopLevel.of(mesh, crease_method)
    for _ in range(steps):
        _, mesh = loop_operator(mesh, crease_method)
    return mesh


def decay_steps(mesh: ControlMesh) -> int:
    """Steps after which no semi-sharp tag is left: ceil of the largest finite sharpness."""
    finite = [float(x) for x in list(mesh.creases.values()) + list(mesh.corners.values()) if 0 < x < INFINITE]
    return int(math.ceil(max(finite, default=0.0)))
