"""Reference (second, independent) regular-face extraction for the tests: 4x4 stencils walked on
the half-edges and per-span blossoms, the way a B-spline textbook does it ("a second,
slower implementation in the tests"). The product uses patching.extraordinary.extraction.


Stencil layout of face f = (v0, v1, v2, v3), half-edges h0..h3 (h_k from v_k to v_{k+1});
``stencil[f, a, b]`` is the vertex in column a (u, along h0) and row b (v, along -h3):

    b=3   (0,3) -- (1,3) -- (2,3) -- (3,3)
            |        |        |        |
    b=2   (0,2) -- v3=(1,2) - v2=(2,2) -- (3,2)
            |        |   f    |        |
    b=1   (0,1) -- v0=(1,1) - v1=(2,1) -- (3,1)
            |        |        |        |
    b=0   (0,0) -- (1,0) -- (2,0) -- (3,0)
           a=0      a=1      a=2      a=3

Walking on quads (all valence-4 interior vertices of the face): for a half-edge g from p to q,
``forward(g) = next(twin(next(g)))`` continues the grid line beyond q, ``backward(g) =
prev(twin(prev(g)))`` before p, and ``next(next(twin(g)))`` is the parallel line one row out.
The span of the face in u needs five leg intervals (``bspline_extraction``): the legs of row 1
from column -1 to 4.  Where such a leg lies beyond an open boundary it does not exist; it can
only matter when the boundary leg next to it has interval 0 (a clamped, multiple knot), where
it is 0 too: the phantom knot of a clamped end.  Otherwise the face is not regular.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tests.reference_bspline import cubic_span_extraction
from patching.topology.tables import Topology

__all__ = ["RegularStencils", "regular_stencils", "regular_extraction_weights", "face_spans"]


def _take(table: np.ndarray, h: np.ndarray) -> np.ndarray:
    """table[h] where h >= 0, -1 elsewhere."""
    return np.where(h >= 0, table[np.maximum(h, 0)], -1)


class _Walker:
    def __init__(self, topo: Topology) -> None:
        self.t = topo

    def nxt(self, h):
        return _take(self.t.next, h)

    def prv(self, h):
        return _take(self.t.prev, h)

    def twin(self, h):
        return _take(self.t.twin, h)

    def forward(self, g):
        return self.nxt(self.twin(self.nxt(g)))

    def backward(self, g):
        return self.prv(self.twin(self.prv(g)))

    def outward(self, g):
        return self.nxt(self.nxt(self.twin(g)))

    def origin(self, h):
        return _take(self.t.origin, h)

    def dest(self, h):
        return _take(self.t.dest, h)


def face_spans(topo: Topology) -> np.ndarray:
    """(f, 2) float64: the face's knot interval in u (edges h0, h2) and in v (h1, h3).

    Zero in either direction: zero parametric area, no patch."""
    base = topo.mesh.face_offsets[:-1]
    return np.stack(
        [topo.halfedge_interval[base], topo.halfedge_interval[base + 1]], axis=1
    )


@dataclass(frozen=True)
class RegularStencils:
    """faces (k,) int64; stencil (k, 4, 4) int64 vertex ids [a, b]; u_intervals, v_intervals
    (k, 5) float64 leg intervals along row 1 (u) and column 1 (v)."""

    faces: np.ndarray
    stencil: np.ndarray
    u_intervals: np.ndarray
    v_intervals: np.ndarray


def _line(w: _Walker, g: np.ndarray) -> np.ndarray:
    """(k, 4) vertices of the grid line through g (columns 0..3 when g is the column 1->2 leg)."""
    return np.stack([w.origin(w.backward(g)), w.origin(g), w.dest(g), w.dest(w.forward(g))], axis=1)


def _leg_intervals(w: _Walker, topo: Topology, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 5) intervals of legs -1..4 along the line of g, and a (k,) mask of lines whose
    missing outer legs cannot be resolved (no leg and the boundary leg is not clamped)."""
    b1 = w.backward(g)
    f1 = w.forward(g)
    # Beyond a boundary vertex there is no straight continuation of the line: phantom leg.
    on_boundary = lambda v: topo.vertex_is_boundary[np.maximum(v, 0)] | (v < 0)  # noqa: E731
    b2 = np.where(on_boundary(w.origin(b1)), -1, w.backward(b1))
    f2 = np.where(on_boundary(w.dest(f1)), -1, w.forward(f1))
    iv = lambda h: np.where(h >= 0, topo.halfedge_interval[np.maximum(h, 0)], 0.0)  # noqa: E731
    e = np.stack([iv(b2), iv(b1), iv(g), iv(f1), iv(f2)], axis=1)
    bad = ((b2 < 0) & (e[:, 1] != 0)) | ((f2 < 0) & (e[:, 3] != 0))
    return e, bad


def regular_stencils(topo: Topology, faces: np.ndarray) -> tuple[RegularStencils, np.ndarray]:
    """Stencils of the given quad faces, all of whose four vertices are interior valence 4.

    Returns the stencils of the faces that are regular, and the ids of those that are not
    (a stencil vertex is an EP, or an outer leg lies beyond a boundary that is not clamped).
    """
    w = _Walker(topo)
    base = topo.mesh.face_offsets[faces]
    h0, h2 = base, base + 2
    h3 = base + 3
    row0 = w.outward(h0)  # (1,0)->(2,0)
    row1 = h0  # (1,1)->(2,1)
    row2 = w.twin(h2)  # (1,2)->(2,2)
    row3 = w.outward(w.twin(row2))  # twin(row2) = h2 -> outward: (2,3)->(1,3), direction -u
    stencil = np.stack([_line(w, row0), _line(w, row1), _line(w, row2), _line(w, row3)[:, ::-1]], axis=2)
    col1 = w.twin(h3)  # (1,1)->(1,2): +v along column 1
    u_iv, u_bad = _leg_intervals(w, topo, row1)
    v_iv, v_bad = _leg_intervals(w, topo, col1)
    # Every stencil vertex must be regular: valence 4 inside, or on the boundary.
    vid = np.maximum(stencil, 0)
    ep = (~topo.vertex_is_boundary[vid]) & (topo.valence[vid] != 4)
    bad = u_bad | v_bad | (stencil < 0).any(axis=(1, 2)) | ep.any(axis=(1, 2))
    keep = ~bad
    return (
        RegularStencils(faces[keep], stencil[keep], u_iv[keep], v_iv[keep]),
        faces[bad],
    )


def regular_extraction_weights(stencils: RegularStencils) -> np.ndarray:
    """(k, 4, 4, 4, 4) weights W[., i, j, a, b]: net[i, j] = sum_ab W P[stencil[a, b]].

    The tensor product of the u and v span extractions (docs/knots.md knot convention)."""
    wu = cubic_span_extraction(stencils.u_intervals)  # (k, i, a)
    wv = cubic_span_extraction(stencils.v_intervals)  # (k, j, b)
    return np.einsum("kia,kjb->kijab", wu, wv)
