"""The patched surface: Bézier coefficient nets per face plus the topology that the B-rep shares.

Point ordering, written once.  A patch of bi-degree d has coefficients
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
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from patching.util.parallel import product
from patching.validation import as_points, check_points, used_size

__all__ = ["CORNER_PARAMETERS", "PatchGroup", "PatchTopology", "SidePieces", "BezierSurface", "OperatorGroup", "SurfaceOperator"]

#: (s, t) of the patch corners 0..3, in the face's vertex order.
CORNER_PARAMETERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@dataclass(frozen=True)
class PatchGroup:
    """Patches of one bi-degree.

    degree: d (3 for bicubic, 5 for bi-quintic).
    faces: (k,) int64, the mesh face each patch covers.
    coefficients: (k, d+1, d+1, 3) float64, see the module docstring for the ordering.
    spans: optional (k, 2) float64, each patch's knot intervals along s and t, where the
        refinement that made the patches knows them (the adaptive path, whose patches cover
        faces of several levels); None: those of the faces (``export.pack.patch_spans``).
    """

    degree: int
    faces: np.ndarray
    coefficients: np.ndarray
    spans: np.ndarray | None = None

    def __repr__(self) -> str:
        return f"PatchGroup(degree {self.degree}, {len(self.faces)} patches)"


@dataclass(frozen=True)
class SidePieces:
    """The sides of all patches as runs of B-rep edges (``PatchTopology.pieces``).

    Sides are numbered ``4 row + side``; side i is made of pieces
    ``indptr[i] .. indptr[i+1] - 1``, in order along the side (corner k to corner k+1).

    indptr: (4 p + 1,) int64.
    edge: (m,) int64, the B-rep edge of each piece.
    reversed: (m,) bool, True where the piece runs against its edge's own direction.
    range: (m, 2) float64, [u0, u1] of the side that the piece covers, u in the side's own
        direction (0 at corner k, 1 at corner k+1); the pieces of a side tile [0, 1].
    vertex: (m, 2) int64, the vertex at u0 and at u1: the side's corner vertices at u = 0
        and u = 1, T-vertices at the break points in between.
    """

    indptr: np.ndarray
    edge: np.ndarray
    reversed: np.ndarray
    range: np.ndarray
    vertex: np.ndarray

    @cached_property
    def side(self) -> np.ndarray:
        """(m,) int64, the side (4 row + side) of each piece."""
        return np.repeat(np.arange(self.indptr.size - 1), np.diff(self.indptr))

    @cached_property
    def whole(self) -> np.ndarray:
        """(m,) bool, pieces that are their whole side ([u0, u1] = [0, 1])."""
        return (self.range[:, 0] == 0.0) & (self.range[:, 1] == 1.0)


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

    Split sides (T-junctions, where patches of different refinement levels meet): a side may
    be a run of several edges.  Then the five ``side_indptr .. piece_vertex`` arrays are set
    (all or none; ``SidePieces`` documents them, ``pieces`` returns them as one object):

    side_indptr: (4 p + 1,) int64, CSR over the sides 4 row + side.
    piece_edge: (m,) int64, piece_reversed: (m,) bool, as side_edge / side_reversed per piece.
    piece_range: (m, 2) float64, [u0, u1] along the side (u: 0 at corner k, 1 at k+1).
    piece_vertex: (m, 2) int64, vertex at u0 and u1; interior break points are T-vertices,
        ordinary vertex ids (counted in n_vertices) that lie inside this side.
    A side that is one whole edge has one piece [0, 1] and keeps side_edge / side_reversed;
    a split side has side_edge = -1 and side_reversed = False, so code that knows only
    side_edge must refuse such a topology (``require_whole_sides``).  Every piece of an edge
    is the same curve: an edge's own direction and 3D curve are those of its first piece (in
    piece order) that is a whole side, else of its first piece (the de Casteljau piece of
    that side's row).  At a T-junction the whole side is the fine patch's side, the pieces
    on the coarse side run the other way, so they are reversed.
    """

    corner_vertex: np.ndarray
    side_edge: np.ndarray
    side_reversed: np.ndarray
    n_vertices: int
    n_edges: int
    side_indptr: np.ndarray | None = None
    piece_edge: np.ndarray | None = None
    piece_reversed: np.ndarray | None = None
    piece_range: np.ndarray | None = None
    piece_vertex: np.ndarray | None = None

    @property
    def has_split_sides(self) -> bool:
        """True when the piece arrays are given and some side is made of several edges."""
        return self.side_indptr is not None and bool(np.any(np.diff(self.side_indptr) != 1))

    @cached_property
    def pieces(self) -> SidePieces:
        """Every side as pieces: the given piece arrays, or one whole piece per side."""
        if self.side_indptr is not None:
            return SidePieces(
                np.asarray(self.side_indptr, dtype=np.int64),
                np.asarray(self.piece_edge, dtype=np.int64),
                np.asarray(self.piece_reversed, dtype=bool),
                np.asarray(self.piece_range, dtype=np.float64).reshape(-1, 2),
                np.asarray(self.piece_vertex, dtype=np.int64).reshape(-1, 2),
            )
        corner = np.asarray(self.corner_vertex, dtype=np.int64)
        n = corner.size
        return SidePieces(
            np.arange(n + 1, dtype=np.int64),
            np.asarray(self.side_edge, dtype=np.int64).ravel(),
            np.asarray(self.side_reversed, dtype=bool).ravel(),
            np.tile([0.0, 1.0], (n, 1)),
            np.stack([corner, np.roll(corner, -1, axis=1)], axis=-1).reshape(n, 2),
        )

    def require_whole_sides(self, what: str) -> None:
        """Raise UnsupportedError naming ``what`` when some side is split (T-junctions)."""
        if self.has_split_sides:
            from patching.errors import UnsupportedError

            rows = np.flatnonzero(np.diff(self.side_indptr) != 1) // 4
            raise UnsupportedError(
                f"{what} needs one edge per patch side; this surface has T-junctions", f"patch {int(rows[0])}"
            )

    @property
    def edge_use_count(self) -> np.ndarray:
        """(n_edges,) int64, how many patch sides (pieces) use each edge (2 inside, 1 on a boundary)."""
        return np.bincount(self.pieces.edge, minlength=self.n_edges)

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

    def __repr__(self) -> str:
        """Counts, not arrays: ``BezierSurface('cube', 24 patches: 24 of degree 5, size 3.46)``."""
        degrees = ", ".join(f"{len(g.faces)} of degree {g.degree}" for g in self.groups)
        return f"BezierSurface({self.name!r}, {self.n_patches} patches: {degrees}, size {self.size:.6g})"

    def patches(self):
        """Yield (row, degree, face, (d+1, d+1, 3) coefficients) for every patch in row order."""
        row = 0
        for g in self.groups:
            for face, net in zip(g.faces, g.coefficients):
                yield row, g.degree, int(face), net
                row += 1


@dataclass(frozen=True)
class OperatorGroup:
    """Rows of one degree: ``faces`` (k,) mesh faces, rows from ``row_offset``; ``spans``
    optional (k, 2) knot intervals of the patches (``PatchGroup.spans``)."""

    degree: int
    faces: np.ndarray
    row_offset: int
    spans: np.ndarray | None = None

    @property
    def n_rows(self) -> int:
        return len(self.faces) * (self.degree + 1) ** 2


@dataclass(frozen=True)
class SurfaceOperator:
    """M and what is needed to turn M @ P into a BezierSurface."""

    matrix: sp.csr_matrix
    groups: tuple[OperatorGroup, ...]
    topology: PatchTopology
    name: str

    def coefficients(self, points: np.ndarray) -> np.ndarray:
        """(rows, 3) Bézier coefficients for control points (n, 3): one sparse product."""
        return product(self.matrix, np.asarray(points, dtype=np.float64))

    def evaluate(self, points: np.ndarray) -> BezierSurface:
        """The patches for control points (n, 3): finite, one row per column of M (MeshError
        naming ``points`` otherwise), not all on one line (nor on one plane for a closed
        surface).  The size is the diagonal of the used points only."""
        points = as_points(points, "points", rows=self.matrix.shape[1])
        check_points(points, self.used_points, self.topology.is_closed, self.name)
        coeffs = self.coefficients(points)
        groups = []
        for g in self.groups:
            d = g.degree
            block = coeffs[g.row_offset : g.row_offset + g.n_rows].reshape(-1, d + 1, d + 1, 3)
            groups.append(PatchGroup(d, g.faces, block, g.spans))
        size = used_size(points, self.used_points)  # a stray unused vertex does not count
        return BezierSurface(tuple(groups), self.topology, self.name, size)

    @cached_property
    def used_points(self) -> np.ndarray:
        """Column ids (control points) that some coefficient depends on, sorted."""
        m = self.matrix.tocsr()
        return np.unique(m.indices[m.data != 0])

    @cached_property
    def row_sums(self) -> np.ndarray:
        return np.asarray(self.matrix.sum(axis=1)).ravel()

