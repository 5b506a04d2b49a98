"""Topology tables of a control mesh: half-edges, edges, vertices, strips (docs/knots.md).

Half-edge h of face f runs from ``origin[h]`` to ``origin[next[h]]``; half-edges are numbered as
the flat face-vertex list, so face f owns ``face_offsets[f]:face_offsets[f+1]``.  ``twin[h]`` is
the opposite half-edge of the neighbouring face, -1 on an open boundary.  All tables are numpy
arrays built without Python loops over faces; derived ones are cached on first use.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.errors import KnotError, MeshError, TagError
from patching.mesh.control_mesh import ControlMesh

__all__ = ["Topology"]


class Topology:
    """Connectivity of a manifold, consistently oriented polygon mesh.

    Raises MeshError (naming the edge or vertex) for an edge shared by more than two faces,
    inconsistent orientation across an edge, or a non-manifold vertex; TagError for a tag on an
    edge that does not exist; KnotError for two different intervals on one strip.
    """

    def __init__(self, mesh: ControlMesh) -> None:
        self.mesh = mesh
        n_he = mesh.face_vertices.shape[0]
        offsets = mesh.face_offsets
        sizes = np.diff(offsets)
        self.n_faces = int(sizes.size)
        self.n_vertices = mesh.n_vertices
        self.origin = mesh.face_vertices.astype(np.int64)
        self.face = np.repeat(np.arange(self.n_faces, dtype=np.int64), sizes)
        local = np.arange(n_he, dtype=np.int64) - offsets[self.face]
        self.next = offsets[self.face] + (local + 1) % sizes[self.face]
        self.prev = offsets[self.face] + (local - 1) % sizes[self.face]
        self.dest = self.origin[self.next]
        self._build_edges()
        self._check_manifold_vertices()

    #: Cached tables of the connectivity alone, which ``retagged`` keeps (it drops every other
    #: cached table: those of the intervals and creases, and any added later).
    _CONNECTIVITY = frozenset(("valence", "vertex_is_boundary", "vertex_is_used", "extraordinary", "outgoing",
                               "vertex_outgoing", "edge_strip", "n_strips"))

    def retagged(self, mesh: ControlMesh) -> "Topology":
        """The Topology of ``mesh``, a mesh with this one's vertices count and faces but other
        tags: the connectivity tables and the checks on them are this one's (not computed
        again), the tables of intervals and creases are ``mesh``'s own when first asked for.
        Its tags' checks (TagError, KnotError) run then, as for ``Topology(mesh)``."""
        if mesh.n_vertices != self.n_vertices or not (
            np.array_equal(mesh.face_offsets, self.mesh.face_offsets) and np.array_equal(mesh.face_vertices, self.mesh.face_vertices)
        ):
            raise ValueError("retagged: the mesh has other faces")
        cached = {k for k, v in vars(Topology).items() if isinstance(v, cached_property)}
        out = object.__new__(Topology)
        out.__dict__.update({k: v for k, v in self.__dict__.items() if k not in cached or k in self._CONNECTIVITY})
        out.mesh = mesh
        return out

    # -- edges and twins ------------------------------------------------------------------
    def _build_edges(self) -> None:
        lo = np.minimum(self.origin, self.dest)
        hi = np.maximum(self.origin, self.dest)
        key = lo * self.n_vertices + hi
        edge_keys, edge_of, counts = np.unique(key, return_inverse=True, return_counts=True)
        self.edge_of = edge_of.astype(np.int64)
        self.edges = np.stack([edge_keys // self.n_vertices, edge_keys % self.n_vertices], axis=1)
        self.n_edges = int(edge_keys.size)
        crowded = np.flatnonzero(counts > 2)
        if crowded.size:
            a, b = self.edges[crowded[0]]
            faces = np.sort(self.face[self.edge_of == crowded[0]])
            raise MeshError(
                f"non-manifold: edge {a}-{b} is shared by {counts[crowded[0]]} faces "
                f"({', '.join(map(str, faces))})",
                self._face_where(int(faces[2])),
            )
        # Two half-edges of one edge: twins if they run in opposite directions.
        order = np.argsort(self.edge_of, kind="stable")
        starts = np.searchsorted(self.edge_of[order], np.arange(self.n_edges))
        first = order[starts]
        second = np.where(counts == 2, order[np.minimum(starts + 1, order.size - 1)], -1)
        same_direction = (counts == 2) & (self.origin[first] == self.origin[np.maximum(second, 0)])
        if same_direction.any():
            e = int(np.flatnonzero(same_direction)[0])
            a, b = self.edges[e]
            f1, f2 = sorted((int(self.face[first[e]]), int(self.face[second[e]])))
            raise MeshError(
                f"faces {f1} and {f2} have opposite orientations across edge {a}-{b}",
                self._face_where(f2),
            )
        self.twin = np.full(self.origin.size, -1, dtype=np.int64)
        pair = counts == 2
        self.twin[first[pair]] = second[pair]
        self.twin[second[pair]] = first[pair]
        self.edge_halfedge = first  # one half-edge of every edge
        self.edge_is_boundary = counts == 1

    def _face_where(self, f: int) -> str:
        return self.mesh.locations.get(("face", f), f"face {f}")

    def _check_manifold_vertices(self) -> None:
        """Faces around each vertex must form one fan (a disc or half-disc)."""
        n_he = self.origin.size
        # Outgoing half-edges h and twin(prev(h)) are neighbours around origin(h).
        around = self.twin[self.prev]
        linked = np.flatnonzero(around >= 0)
        graph = sp.coo_matrix(
            (np.ones(linked.size), (linked, around[linked])), shape=(n_he, n_he)
        )
        n_comp, label = connected_components(graph, directed=False)
        fans = np.zeros(self.n_vertices, dtype=np.int64)
        comp_vertex = np.full(n_comp, -1, dtype=np.int64)
        comp_vertex[label] = self.origin
        np.add.at(fans, comp_vertex, 1)
        bad = np.flatnonzero(fans > 1)
        if bad.size:
            v = int(bad[0])
            raise MeshError(
                f"non-manifold: vertex {v} joins {fans[v]} separate fans of faces",
                self.mesh.locations.get(("vertex", v), f"vertex {v}"),
            )

    # -- vertices -------------------------------------------------------------------------
    @cached_property
    def valence(self) -> np.ndarray:
        """(n,) int64, number of edges at each vertex (0 for isolated vertices)."""
        return np.bincount(self.edges.ravel(), minlength=self.n_vertices)

    @cached_property
    def vertex_is_boundary(self) -> np.ndarray:
        """(n,) bool, vertex on an open boundary."""
        out = np.zeros(self.n_vertices, dtype=bool)
        out[self.edges[self.edge_is_boundary].ravel()] = True
        return out

    @cached_property
    def vertex_is_used(self) -> np.ndarray:
        out = np.zeros(self.n_vertices, dtype=bool)
        out[self.origin] = True
        return out

    @cached_property
    def extraordinary(self) -> np.ndarray:
        """(k,) int64 ids of interior vertices whose valence is not 4 (EPs)."""
        mask = self.vertex_is_used & ~self.vertex_is_boundary & (self.valence != 4)
        return np.flatnonzero(mask)

    @cached_property
    def outgoing(self) -> np.ndarray:
        """(n,) int64: one outgoing half-edge per vertex; for a boundary vertex the one whose
        edge lies on the boundary, so that rotating with ``rotate`` visits the whole fan."""
        out = np.full(self.n_vertices, -1, dtype=np.int64)
        out[self.origin[::-1]] = np.arange(self.origin.size - 1, -1, -1)
        boundary_out = np.flatnonzero(self.twin < 0)
        out[self.origin[boundary_out]] = boundary_out
        return out

    @cached_property
    def vertex_outgoing(self) -> tuple[np.ndarray, np.ndarray]:
        """(ptr (n + 1,), idx (H,)) int64: the outgoing half-edges of vertex v are
        ``idx[ptr[v]:ptr[v + 1]]``, in no particular order (here ascending; a subdivided mesh's
        Topology derives them from its parent's in another order)."""
        ptr = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(np.bincount(self.origin, minlength=self.n_vertices), out=ptr[1:])
        return ptr, np.argsort(self.origin, kind="stable").astype(np.int64)

    def rotate(self, h: np.ndarray) -> np.ndarray:
        """Next outgoing half-edge around origin(h), clockwise seen from outside: twin(prev(h)).
        -1 where that crosses the boundary."""
        h = np.asarray(h)
        return np.where(h >= 0, self.twin[self.prev[np.maximum(h, 0)]], -1)

    def rotate_back(self, h: np.ndarray) -> np.ndarray:
        """The inverse of ``rotate``: next(twin(h)); -1 where that crosses the boundary."""
        h = np.asarray(h)
        t = np.where(h >= 0, self.twin[np.maximum(h, 0)], -1)
        return np.where(t >= 0, self.next[np.maximum(t, 0)], -1)

    def fans(self, vertices: np.ndarray):
        """Yield (ring, boundary) per group of ``vertices`` with the same number of faces and
        boundary flag: ring (E, k) their outgoing half-edges in rotation order (one per face),
        a boundary vertex's starting at its boundary edge (``outgoing``), so it has valence - 1
        of them.  Vectorised over the vertices of a group."""
        vertices = np.asarray(vertices, dtype=np.int64)
        boundary = self.vertex_is_boundary[vertices]
        faces = self.valence[vertices] - boundary
        for b in (False, True):
            for k in np.unique(faces[boundary == b]).tolist():
                vs = vertices[(boundary == b) & (faces == k)]
                ring = np.empty((vs.size, k), dtype=np.int64)
                ring[:, 0] = self.outgoing[vs]
                for i in range(1, k):
                    ring[:, i] = self.rotate(ring[:, i - 1])
                yield ring, b

    def one_ring(self, v: int) -> np.ndarray:
        """Outgoing half-edges of vertex v in rotation order (a small local problem)."""
        start = int(self.outgoing[v])
        ring = [start]
        h = int(self.rotate(np.array(start)))
        while h >= 0 and h != start:
            ring.append(h)
            h = int(self.rotate(np.array(h)))
        return np.array(ring, dtype=np.int64)

    # -- strips and intervals -------------------------------------------------------------
    @cached_property
    def edge_strip(self) -> np.ndarray:
        """(e,) int64 strip id of every edge: edges linked through opposite edges of quads."""
        quads = np.flatnonzero(np.diff(self.mesh.face_offsets) == 4)
        base = self.mesh.face_offsets[quads]
        a = np.concatenate([self.edge_of[base], self.edge_of[base + 1]])
        b = np.concatenate([self.edge_of[base + 2], self.edge_of[base + 3]])
        graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(self.n_edges, self.n_edges))
        _, label = connected_components(graph, directed=False)
        return label.astype(np.int64)

    @cached_property
    def n_strips(self) -> int:
        return int(self.edge_strip.max()) + 1 if self.n_edges else 0

    def edge_id(self, a: int, b: int) -> int:
        """Edge id of vertex pair a-b, or -1 if there is no such edge."""
        key = min(a, b) * self.n_vertices + max(a, b)
        keys = self.edges[:, 0] * self.n_vertices + self.edges[:, 1]
        i = int(np.searchsorted(keys, key))
        return i if i < keys.size and keys[i] == key else -1

    def _tagged_edges(self, tag: dict, kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(edge ids, values, (k, 2) vertex pairs) of an edge tag; TagError for a missing edge."""
        if not tag:
            return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2), np.int64)
        pairs = np.array(list(tag.keys()), dtype=np.int64).reshape(-1, 2)
        values = np.fromiter(tag.values(), dtype=np.float64, count=len(tag))
        keys = self.edges[:, 0] * self.n_vertices + self.edges[:, 1]
        wanted = pairs[:, 0] * self.n_vertices + pairs[:, 1]
        idx = np.minimum(np.searchsorted(keys, wanted), keys.size - 1)
        missing = np.flatnonzero(keys[idx] != wanted)
        if missing.size:
            a, b = (int(x) for x in pairs[missing[0]])
            raise TagError(
                f"{kind} tag names edge {a}-{b}, which does not exist", self.mesh.where(kind, (a, b))
            )
        return idx, values, pairs

    @cached_property
    def strip_interval(self) -> np.ndarray:
        """(strips,) float64 knot interval of every strip (default 1; docs/knots.md)."""
        out = np.ones(self.n_strips)
        idx, values, pairs = self._tagged_edges(dict(self.mesh.intervals), "interval")
        if idx.size == 0:
            return out
        strips = self.edge_strip[idx]
        order = np.lexsort((values, strips))
        s_sorted, v_sorted = strips[order], values[order]
        clash = np.flatnonzero((s_sorted[1:] == s_sorted[:-1]) & (v_sorted[1:] != v_sorted[:-1]))
        if clash.size:
            i, j = order[clash[0]], order[clash[0] + 1]
            (a, b), (c, d) = pairs[i].tolist(), pairs[j].tolist()
            raise KnotError(
                f"two different intervals on one strip: edge {a}-{b} has {values[i]:g}, "
                f"edge {c}-{d} has {values[j]:g}",
                f"{self.mesh.where('interval', (a, b))} and {self.mesh.where('interval', (c, d))}",
            )
        out[strips] = values
        return out

    @cached_property
    def edge_interval(self) -> np.ndarray:
        """(e,) float64 knot interval of every edge."""
        return self.strip_interval[self.edge_strip]

    @cached_property
    def halfedge_interval(self) -> np.ndarray:
        """(h,) float64 knot interval of every half-edge's edge."""
        return self.edge_interval[self.edge_of]

    @cached_property
    def edge_sharpness(self) -> np.ndarray:
        """(e,) float64 crease sharpness (0 smooth, >= 10 infinitely sharp)."""
        out = np.zeros(self.n_edges)
        idx, values, _ = self._tagged_edges(dict(self.mesh.creases), "crease")
        out[idx] = values
        return out

    @cached_property
    def face_spans(self) -> np.ndarray:
        """(f, 2) float64: the face's knot interval in u (edges h0, h2) and in v (h1, h3).

        Zero in either direction: zero parametric area, no patch."""
        base = self.mesh.face_offsets[:-1]
        return np.stack([self.halfedge_interval[base], self.halfedge_interval[base + 1]], axis=1)

    def strips_summary(self) -> list[tuple[int, int, float]]:
        """(strip id, number of edges, interval) for every strip."""
        counts = np.bincount(self.edge_strip, minlength=self.n_strips)
        return [(s, int(counts[s]), float(self.strip_interval[s])) for s in range(self.n_strips)]
