"""The linear operator from control points to Bézier coefficients (DESIGN 3).

``SurfaceOperator.matrix`` is a scipy.sparse CSR matrix M with one column per control point and
one row per Bézier coefficient: coefficients = M @ P.  It is built from topology, knot
intervals and tags only, never from positions, so moving control points costs one sparse
product.  Rows come in groups of one degree; inside a group, patch k of bi-degree d owns rows
``offset + k (d+1)^2 + i (d+1) + j`` for its coefficient net[i, j] (see ``surface``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .errors import UnsupportedError
from .mesh import ControlMesh
from .patch_topology import patch_topology
from .regular_faces import face_spans, regular_extraction_weights, regular_stencils
from .surface import BezierSurface, PatchGroup, PatchTopology
from .topology import Topology

__all__ = ["SurfaceOperator", "build_operator", "build"]


@dataclass(frozen=True)
class OperatorGroup:
    """Rows of one degree: ``faces`` (k,) mesh faces, rows from ``row_offset``."""

    degree: int
    faces: np.ndarray
    row_offset: int

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
        return self.matrix @ np.asarray(points, dtype=np.float64)

    def evaluate(self, points: np.ndarray) -> BezierSurface:
        """The patches for control points (n, 3)."""
        points = np.asarray(points, dtype=np.float64)
        coeffs = self.coefficients(points)
        groups = []
        for g in self.groups:
            d = g.degree
            block = coeffs[g.row_offset : g.row_offset + g.n_rows].reshape(-1, d + 1, d + 1, 3)
            groups.append(PatchGroup(d, g.faces, block))
        size = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
        return BezierSurface(tuple(groups), self.topology, self.name, size)

    @cached_property
    def row_sums(self) -> np.ndarray:
        return np.asarray(self.matrix.sum(axis=1)).ravel()


def _refuse_unsupported(topo: Topology) -> None:
    """Refuse, with the place named, what later issues will build: never a wrong surface."""
    mesh = topo.mesh
    sizes = mesh.face_sizes
    nonquad = np.flatnonzero(sizes != 4)
    if nonquad.size:
        f = int(nonquad[0])
        raise UnsupportedError(
            f"face {f} has {int(sizes[f])} vertices; non-quad faces are not supported yet",
            mesh.where("face", f),
        )
    sharp = np.flatnonzero(topo.edge_sharpness > 0)
    if sharp.size:
        a, b = (int(x) for x in topo.edges[sharp[0]])
        raise UnsupportedError(
            f"crease on edge {a}-{b}: sharp and semi-sharp creases are not supported yet",
            mesh.where("crease", (a, b)),
        )
    corners = [v for v, s in mesh.corners.items() if s > 0]
    if corners:
        raise UnsupportedError(
            f"corner tag on vertex {corners[0]}: corners are not supported yet",
            mesh.where("corner", corners[0]),
        )
    if mesh.holes:
        f = min(mesh.holes)
        raise UnsupportedError(f"hole tag on face {f}: holes are not supported yet", mesh.where("hole", f))


def build_operator(mesh: ControlMesh, topology: Topology | None = None) -> SurfaceOperator:
    """Build M for a mesh (issue 3: regular all-quad meshes, closed or with clamped borders)."""
    topo = topology or Topology(mesh)
    _refuse_unsupported(topo)
    spans = face_spans(topo)
    has_area = np.all(spans > 0, axis=1)
    faces = np.flatnonzero(has_area)
    # A face with area needs four interior valence-4 vertices (its 3x3 block of faces).
    fv = mesh.quads()[faces]
    vertex_ok = (~topo.vertex_is_boundary) & (topo.valence == 4)
    ok = vertex_ok[fv].all(axis=1)
    _refuse_irregular(topo, faces[~ok], fv[~ok])
    stencils, irregular = regular_stencils(topo, faces[ok])
    _refuse_irregular(topo, irregular, mesh.quads()[irregular])
    weights = regular_extraction_weights(stencils)  # (k, 4, 4, 4, 4)
    k = len(stencils.faces)
    rows = np.broadcast_to(np.arange(k * 16).reshape(k, 4, 4, 1, 1), weights.shape)
    cols = np.broadcast_to(stencils.stencil[:, None, None, :, :], weights.shape)
    matrix = sp.csr_matrix(
        (weights.ravel(), (rows.ravel(), cols.ravel())), shape=(k * 16, mesh.n_vertices)
    )
    matrix.sum_duplicates()
    groups = (OperatorGroup(3, stencils.faces, 0),)
    ptopo = patch_topology(topo, stencils.faces, spans)
    return SurfaceOperator(matrix, groups, ptopo, mesh.name)


def _refuse_irregular(topo: Topology, faces: np.ndarray, fv: np.ndarray) -> None:
    if faces.size == 0:
        return
    mesh = topo.mesh
    f = int(faces[0])
    ep = topo.extraordinary
    near_ep = np.intersect1d(fv.ravel(), ep)
    if near_ep.size:
        v = int(near_ep[0])
        raise UnsupportedError(
            f"extraordinary point at vertex {v} (valence {int(topo.valence[v])}): "
            "faces touching extraordinary points are not supported yet",
            mesh.where("face", f),
        )
    if topo.vertex_is_boundary[fv].any():
        raise UnsupportedError(
            f"face {f} lies on an open boundary with a non-zero knot interval: open boundaries "
            "are only supported with zero (clamped) outer strips so far",
            mesh.where("face", f),
        )
    raise UnsupportedError(
        f"face {f} has an extraordinary point in its 4x4 neighbourhood or an unclamped boundary "
        "beyond it: not supported yet",
        mesh.where("face", f),
    )


def build(mesh: ControlMesh) -> BezierSurface:
    """The patched surface of a mesh: ``build_operator(mesh).evaluate(mesh.vertices)``."""
    return build_operator(mesh).evaluate(mesh.vertices)
