"""What one Catmull-Clark step reads of the parent mesh: topology, knot intervals and
sharpness levels gathered into arrays (``_Context``), and the triplet rows of S (``TripletRows``).
Shared by the modules of ``subdivision`` only."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.rules.catmark import (
    CORNER,
    CREASE,
    DART,
    SMOOTH,
)
from patching.rules.crease import child_edge_sharpness, decrement
from patching.topology.cache import topology_of


@dataclass
class _Level:
    """Tags of one sharpness level (the parent's, or the child's after decrementing)."""

    sharp: np.ndarray  # (e,) bool
    vertex_sharp: np.ndarray  # (v,) bool
    rule: np.ndarray  # (v,) int8: SMOOTH, DART, CREASE, CORNER
    crease_edges: np.ndarray  # (v, 2) int64: the two sharp edges of a CREASE vertex, else -1


class _Context:
    """Topology tables, intervals and tags of one mesh, as flat arrays (read-only)."""

    def __init__(self, mesh: ControlMesh, crease_method: str = "uniform") -> None:
        t = topology_of(mesh)  # derived from the parent's when the mesh is a child
        self.mesh, self.topo = mesh, t
        self.crease_method = crease_method
        self.H = t.origin.size
        self.nf, self.ne, self.nv = t.n_faces, t.n_edges, t.n_vertices
        self.origin, self.dest, self.nxt, self.prv = t.origin, t.dest, t.next, t.prev
        self.twin, self.face, self.eoh, self.edges = t.twin, t.face, t.edge_of, t.edges
        self.fsize = np.diff(mesh.face_offsets)
        self.ksize = self.fsize[self.face]  # (H,) size of the face of each half-edge
        self.d_e = t.edge_interval
        self.d_h = t.halfedge_interval
        si = t.strip_interval
        self.uniform = bool(si.size == 0 or np.all(si == si[0]))
        self.valence = t.valence
        self.n_faces_at = np.bincount(self.origin, minlength=self.nv)
        self.v_boundary = t.vertex_is_boundary
        self.e_boundary = t.edge_is_boundary
        # Sharpness: infinite at >= 10 and on every boundary edge (OpenSubdiv, all modes).
        es = t.edge_sharpness.copy()
        es[es >= INFINITELY_SHARP] = np.inf
        es[self.e_boundary] = np.inf
        self.es = es
        vs = np.zeros(self.nv)
        if mesh.corners:
            idx = np.fromiter(mesh.corners.keys(), np.int64)
            vs[idx] = np.fromiter(mesh.corners.values(), np.float64)
        vs[vs >= INFINITELY_SHARP] = np.inf
        if mesh.interpolate_boundary == 1:
            topological_corner = self.v_boundary & (self.n_faces_at == 1) & (self.valence == 2)
            vs[topological_corner] = np.inf
        self.vs = vs
        # [OSD] TRI_SUB_SMOOTH: the smooth edge points beside triangles take other weights.
        self.smooth_triangles = mesh.triangle_subdivision == "smooth" and bool((self.fsize == 3).any())
        # Vertex touches a non-quad face.
        self.v_nonquad = np.zeros(self.nv, bool)
        self.v_nonquad[self.origin[self.ksize != 4]] = True

    # -- levels -------------------------------------------------------------------------------
    def level(self, es: np.ndarray, vs: np.ndarray) -> _Level:
        """Rules from edge sharpness ``es``, (e,) or (e, 2) per end ``edges[:, k]`` (the
        child's halves, which Chaikin creasing may give two values), and vertex sharpness."""
        es = np.stack([es, es], axis=1) if es.ndim == 1 else es
        at_end = es > 0
        sharp = at_end.any(axis=1)
        count = np.bincount(self.edges[at_end], minlength=self.nv)
        vsharp = vs > 0
        rule = np.where(vsharp | (count > 2), CORNER, np.minimum(count, 2)).astype(np.int8)
        ends = np.full((self.nv, 2), -1, np.int64)
        s0, s1 = np.flatnonzero(at_end[:, 0]), np.flatnonzero(at_end[:, 1])
        if s0.size + s1.size:
            vv = np.concatenate([self.edges[s0, 0], self.edges[s1, 1]])
            ee = np.concatenate([s0, s1])
            order = np.argsort(vv, kind="stable")
            vv, ee = vv[order], ee[order]
            crease = np.flatnonzero(rule == CREASE)
            first = np.searchsorted(vv, crease)
            ends[crease, 0] = ee[first]
            ends[crease, 1] = ee[first + 1]
        return _Level(sharp, vsharp, rule, ends)

    @cached_property
    def parent(self) -> _Level:
        return self.level(self.es, self.vs)

    @cached_property
    def child_es(self) -> np.ndarray:
        """(e, 2) sharpness of the child half of every edge at its end ``edges[:, k]``."""
        return child_edge_sharpness(self.es, self.edges, self.nv, self.crease_method)

    @cached_property
    def child(self) -> _Level:
        return self.level(self.child_es, decrement(self.vs))

    @cached_property
    def edge_sharp_weight(self) -> np.ndarray:
        """(e,) weight of the crease rule in the edge point, the rest going to the smooth rule
        (``Sdc::Scheme::ComputeEdgeVertexMask`` as ``Far::PrimvarRefiner`` calls it): 0 on a
        smooth edge; 1 when both child halves stay sharp (the child vertex is a crease);
        otherwise the parent sharpness s.  Uniform creasing: ``min(s, 1)``.  Chaikin creasing
        can keep an edge of s < 1 sharp (1) and can clear a half of an edge of s > 1: then
        OpenSubdiv's weight is s itself, unclamped (the smooth rule gets 1 - s < 0), kept so
        that the points equal OpenSubdiv's."""
        both = (self.child_es > 0).all(axis=1)
        return np.where(self.es > 0, np.where(both, 1.0, self.es), 0.0)

    @cached_property
    def smooth_edge_face_weight(self) -> np.ndarray:
        """(e,) weight f of each of the two face points in the smooth edge point
        ``(1/2 - f)(a + b) + f (F_0 + F_1)``: Catmull-Clark's 1/4, or, with smooth triangles
        ([OSD] ``Sdc::Options::TRI_SUB_SMOOTH``, ``Scheme<SCHEME_CATMARK>::
        assignSmoothMaskForEdge``) on an edge of two faces at least one of which is a triangle,
        the mean of 0.47 per triangle and 1/4 per other face (both face points get the mean;
        0.47 is [OSD]'s ``CATMARK_SMOOTH_TRI_EDGE_WEIGHT``, "from Mathematica" in Hbr)."""
        f = np.full(self.ne, 0.25)
        if not self.smooth_triangles:
            return f
        tri = np.zeros(self.ne)
        np.add.at(tri, self.eoh, np.where(self.ksize == 3, 0.47, 0.25))
        two = np.bincount(self.eoh, minlength=self.ne) == 2
        beside = np.zeros(self.ne, bool)
        beside[self.eoh[self.ksize == 3]] = True
        pick = two & beside
        f[pick] = 0.5 * tri[pick]
        return f

    # -- half-edge helpers --------------------------------------------------------------------
    @cached_property
    def face_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(h, h') for every half-edge h and every half-edge h' of the same face."""
        k = self.ksize
        h = np.repeat(np.arange(self.H), k)
        start = np.repeat(np.cumsum(k) - k, k)
        local = np.arange(h.size) - start
        base = self.mesh.face_offsets[self.face[h]]
        return h, base + local

    def _regular_interior(self, rule: int) -> np.ndarray:
        """(v,) bool: interior, valence 4, four quads around it, parent rule ``rule``."""
        return (
            ~self.v_boundary
            & (self.valence == 4)
            & ~self.v_nonquad
            & (self.parent.rule == rule)
            & (self.n_faces_at == 4)
        )

    @cached_property
    def regular_line_vertex(self) -> np.ndarray:
        """(v,) bool: straight lines continue through v (interior, valence 4, quads, untagged)."""
        return self._regular_interior(SMOOTH)

    @cached_property
    def regular_crease_vertex(self) -> np.ndarray:
        """(v,) bool: interior, valence 4, four quads, a CREASE vertex of the parent level
        (whether its two sharp edges are opposite is read per half-edge in ``ahead``)."""
        return self._regular_interior(CREASE)

    @cached_property
    def regular_boundary_vertex(self) -> np.ndarray:
        """(v,) bool: the boundary line continues straight through v (two quads, valence 3,
        no tag but the boundary crease itself)."""
        return (
            self.v_boundary
            & (self.valence == 3)
            & ~self.v_nonquad
            & (self.parent.rule == CREASE)
            & (self.n_faces_at == 2)
        )

    @cached_property
    def ahead(self) -> np.ndarray:
        """(H,) interval beyond dest(h) on h's straight line; h's own where there is no line.

        Lines run straight through regular interior vertices; along an interior crease through
        a regular crease vertex (interior, valence 4, four quads, its two sharp edges
        opposite); and along the boundary through regular boundary vertices: there the crease
        or boundary curve's next interval, as the crease rule (``crease_beyond``) reads it, so
        that the edge and face points beside the curve see the same knots as the curve (beside
        a crease vertex whose spokes are all equal, which takes knot insertion and no
        eigen-polyhedron rule, the crossing edges' points read the crease's own interval
        there before: tests/test_crease_tensor.py).  A crease, like a boundary, ends the lines
        that cross it.  At a clamped side (docs/knots.md) the boundary's reading keeps the
        zero strips degenerate: every point of a zero strip lies on the boundary."""
        out = self.d_h.copy()
        b = self.dest
        hs = np.flatnonzero(self.regular_line_vertex[b])
        c = self.nxt[self.twin[self.nxt[hs]]]
        out[hs] = self.d_h[c]
        # along an interior crease: h sharp and its straight continuation c sharp too (a
        # CREASE vertex has exactly two sharp edges, so these are they, opposite spokes; where
        # the crease turns, c is smooth and h keeps its own interval)
        lev = self.parent
        hc = np.flatnonzero(self.regular_crease_vertex[b] & lev.sharp[self.eoh])
        c = self.nxt[self.twin[self.nxt[hc]]]
        straight = lev.sharp[self.eoh[c]]
        out[hc[straight]] = self.d_h[c[straight]]
        # along the boundary: h's edge is a boundary edge, next(h) the spoke into the interior
        hb = np.flatnonzero(self.regular_boundary_vertex[b] & (self.twin < 0) & (self.twin[self.nxt] >= 0))
        out[hb] = self.d_h[self.nxt[self.twin[self.nxt[hb]]]]
        return out

    def ahead_back(self, h: np.ndarray) -> np.ndarray:
        """Interval beyond origin(h), backwards along h (through the twin; along the boundary
        through a regular boundary vertex; else h's own interval)."""
        t = self.twin[h]
        back = self.twin[self.prv[h]]  # spoke leaving origin(h) in the neighbouring face
        along = (t < 0) & self.regular_boundary_vertex[self.origin[h]] & (back >= 0)
        other = self.d_h[self.prv[np.maximum(back, 0)]]
        return np.where(t >= 0, self.ahead[np.maximum(t, 0)], np.where(along, other, self.d_h[h]))

    def crease_beyond(self, lev: _Level, e: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Interval beyond vertex v along the crease curve through sharp edge e."""
        e0, e1 = lev.crease_edges[v, 0], lev.crease_edges[v, 1]
        other = np.where(e0 == e, e1, e0)
        through = lev.rule[v] == CREASE
        return np.where(through, self.d_e[np.maximum(other, 0)], self.d_e[e])

    # -- sectors (seed rules) -----------------------------------------------------------------
    def theta_at(self, lev: _Level, h: np.ndarray) -> np.ndarray:
        """BLZ's theta at origin(h) for the untagged edge of h (NaN where origin is untagged)."""
        label, m, alpha = self._sectors(lev)
        lab = np.maximum(label[h], 0)
        rule = lev.rule[self.origin[h]]
        theta = np.full(h.size, np.nan)
        theta = np.where(rule == DART, 2 * math.pi / m[lab], theta)
        theta = np.where(rule == CREASE, math.pi / m[lab], theta)
        theta = np.where(rule == CORNER, alpha[lab] / m[lab], theta)
        return theta

    def _sectors(self, lev: _Level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sectors of the tagged vertices of ``lev``: (H,) sector of every corner at a tagged
        vertex (-1 elsewhere), and each sector's number of faces and topological angle (sum of
        ``pi (k - 2) / k``).  A corner h is linked to the corner across edge prev(h) unless
        that edge is sharp; only corners at tagged vertices enter the graph.  Cached per level."""
        cache = self.__dict__.setdefault("_sector_cache", {})
        hit = cache.get(id(lev))
        if hit is not None and hit[0] is lev:
            return hit[1]
        nodes = np.flatnonzero(lev.rule[self.origin] != SMOOTH)
        local = np.full(self.H, -1, np.int64)
        local[nodes] = np.arange(nodes.size)
        into = self.twin[self.prv[nodes]]  # the corner across edge prev(h): the same vertex
        link = np.flatnonzero((into >= 0) & ~lev.sharp[self.eoh[self.prv[nodes]]])
        g = sp.coo_matrix((np.ones(link.size), (link, local[into[link]])), shape=(nodes.size, nodes.size))
        _, lab = connected_components(g, directed=False)
        k = self.ksize[nodes]
        m = np.bincount(lab, minlength=1).astype(np.float64)
        alpha = np.bincount(lab, weights=math.pi * (k - 2) / k, minlength=1)
        label = np.full(self.H, -1, np.int64)
        label[nodes] = lab
        cache[id(lev)] = (lev, (label, np.maximum(m, 1.0), alpha))
        return cache[id(lev)][1]
