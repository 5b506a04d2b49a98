"""The patched surface: Bézier coefficient nets per face plus the topology that the B-rep shares.

Point ordering, written once (STYLE 9).  A patch of bi-degree d has coefficients
``coefficients[k, i, j]`` multiplying ``B_i^d(s) B_j^d(t)``.  Its parameter square is laid on
the mesh face ``v0 v1 v2 v3`` (the face's vertex order, counter-clockwise seen from outside):

    t
    ^
    |  v3 (0,1) ------------ v2 (1,1)
    |   |     side 2 (s: 1->0)  |
    |   | side 3                | side 1
    |   | (t: 1->0)             | (t: 0->1)
    |  v0 (0,0) ------------ v1 (1,0)
    |         side 0 (s: 0->1)
    +--------------------------------> s

so ``S_s x S_t`` points to the side the mesh orientation calls outside.  Corner ``c`` of a patch
is the parameter corner ``CORNER_PARAMETERS[c]``; side ``k`` runs from corner ``k`` to corner
``k+1 mod 4``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CORNER_PARAMETERS", "PatchGroup", "PatchTopology", "BezierSurface"]

#: (s, t) of the patch corners 0..3, in the face's vertex order.
CORNER_PARAMETERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@dataclass(frozen=True)
class PatchGroup:
    """Patches of one bi-degree.

    degree: d (3 for bicubic, 5 for bi-quintic).
    faces: (k,) int64, the mesh face each patch covers.
    coefficients: (k, d+1, d+1, 3) float64, see the module docstring for the ordering.
    """

    degree: int
    faces: np.ndarray
    coefficients: np.ndarray


@dataclass(frozen=True)
class PatchTopology:
    """How patch corners and sides are shared, for a B-rep built with shared topology.

    Rows follow the patches in the order of ``BezierSurface.groups`` concatenated.

    corner_vertex: (p, 4) int64, id of the B-rep vertex at each corner (0..n_vertices-1).
    side_edge: (p, 4) int64, id of the B-rep edge along each side (0..n_edges-1).
    side_reversed: (p, 4) bool, True where the side runs against the edge's own direction.
        An edge's own direction is the direction of the first side (lowest row, then side
        index) that uses it; its 3D curve is that side's boundary row of coefficients.
    Two patch sides that share an edge class run in opposite directions (consistently
    oriented mesh), and an edge used by one side only lies on the open boundary.
    """

    corner_vertex: np.ndarray
    side_edge: np.ndarray
    side_reversed: np.ndarray
    n_vertices: int
    n_edges: int

    @property
    def edge_use_count(self) -> np.ndarray:
        """(n_edges,) int64, how many patch sides use each edge (2 inside, 1 on a boundary)."""
        return np.bincount(self.side_edge.ravel(), minlength=self.n_edges)

    @property
    def is_closed(self) -> bool:
        """True when every edge is shared by exactly two sides: the patches bound a solid."""
        return bool(self.n_edges > 0 and np.all(self.edge_use_count == 2))


@dataclass(frozen=True)
class BezierSurface:
    """All patches of a mesh, grouped by degree, with their shared topology.

    name: the product name for export (the input file's stem).
    size: the diagonal of the control points' bounding box, the length that tolerances
        are relative to.
    """

    groups: tuple[PatchGroup, ...]
    topology: PatchTopology
    name: str
    size: float

    @property
    def n_patches(self) -> int:
        return int(sum(len(g.faces) for g in self.groups))

    def patches(self):
        """Yield (row, degree, face, (d+1, d+1, 3) coefficients) for every patch in row order."""
        row = 0
        for g in self.groups:
            for face, net in zip(g.faces, g.coefficients):
                yield row, g.degree, int(face), net
                row += 1
