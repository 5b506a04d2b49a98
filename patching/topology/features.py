"""Sharp features of a control mesh as the patch construction sees them ([FSLYJ] sec. 4.2).

Infinitely sharp edges (sharpness >= 10, and the open boundary when it is interpolated) cut the
faces around a vertex into *sectors*: maximal fans of faces between two sharp edges.  Section
4.2 treats each sector on its own: the crease curve is the cubic B-spline of its polygon
(triple knots: nothing crosses it), the angles of a sector add up to pi where a crease runs on
through the vertex, and no G1 constraint crosses a sharp spoke.  So every sector is, locally, a
boundary fan of an open mesh cut along its sharp edges, and needs anchors (the EP path of
[FSLYJ] sec. 3) unless it is one of the fans the bicubic construction already reproduces:

* one face: a corner (the patch keeps the control point), or a crease turning through the
  vertex (the patch corner is flat);
* two faces at a crease vertex that is not a corner: the regular crease/boundary fan.

A vertex is a *corner* when it carries a corner tag >= 10, when three or more sharp edges meet,
or (interpolateboundary 1) when it is a boundary vertex with one face.  Two sharp edges and no
tag make a crease vertex, whatever the angle between them (OpenSubdiv's rule).  One sharp edge
at an interior vertex is a dart: the crease fades out there ([TLC] sec. 4's dart vertex
takes the smooth rule), so the vertex keeps the smooth vertex point and its ring is one sector
of 2 pi in which the sharp spoke only loses its G1 constraint (its curve is not pinned to the
crease polygon, whose B-spline would end at the control point).  An interior vertex of
valence 2 gets the EP path too, its two patches meeting at flat (pi) corners.

Sector angles (section 4.2 gives only the crease rule):
* crease vertex: pi per sector (the paper), the open boundary included;
* corner: the sector's topological angle, pi / 2 per quad as [TLC]'s corner rules read in
  ``subdivision`` (a three-quad concave sector spans 3 pi / 2), but never a multiple of pi, so
  that the two crease legs fix the sector's tangent plane (``g1_patches.corner_sector_angle``);
* corner tag on a vertex without sharp edges, and a dart: one sector of 2 pi (2 pi / n per
  patch, a skewed fan at valence 4: ``g1_patches.FOUR_FAN``); the tagged vertex is
  interpolated.

Under interpolateboundary 0 the faces at the boundary give no surface
(``faces_without_surface``) and boundary vertices never take the EP path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from patching.errors import UnsupportedError
from patching.mesh.control_mesh import INFINITELY_SHARP
from patching.topology.tables import Topology

__all__ = ["Features", "features", "sharp_edges", "corner_vertices", "faces_without_surface", "refuse_singular_rings"]

CREASE_SECTOR = np.pi
CORNER_SECTOR = np.pi / 2


def sharp_edges(topo: Topology) -> np.ndarray:
    """(e,) bool: infinitely sharp edges, and the open boundary when it is interpolated
    (interpolateboundary 1 or 2, docs/input.md: boundary edges are infinitely sharp creases)."""
    sharp = topo.edge_sharpness >= INFINITELY_SHARP
    if topo.mesh.interpolate_boundary in (1, 2):
        sharp = sharp | topo.edge_is_boundary
    return sharp


def corner_vertices(topo: Topology, sharp: np.ndarray | None = None) -> np.ndarray:
    """(n,) bool: interpolated corners: corner tag >= 10, three or more sharp edges, or a
    boundary vertex with one face under interpolateboundary 1 (mode 2 smooths those: the
    boundary crease turns through them)."""
    if sharp is None:
        sharp = sharp_edges(topo)
    count = np.bincount(topo.edges[sharp].ravel(), minlength=topo.n_vertices)
    corner = count >= 3
    tagged = [v for v, s in topo.mesh.corners.items() if s >= INFINITELY_SHARP]
    corner[tagged] = True
    if topo.mesh.interpolate_boundary == 1:
        corner |= topo.vertex_is_boundary & (topo.valence == 2)
    return corner & topo.vertex_is_used


def faces_without_surface(topo: Topology) -> np.ndarray:
    """(f,) bool: faces that give no patch whatever their intervals: holes (``t hole``) and,
    under interpolateboundary 0, every face with a vertex on the open boundary (OpenSubdiv's
    "none": the limit surface stops one ring inside; docs/input.md).  Their control points still
    shape the faces around them, whose rules do not change."""
    out = np.zeros(topo.mesh.n_faces, dtype=bool)
    out[list(topo.mesh.holes)] = True
    if topo.mesh.interpolate_boundary == 0:
        out[np.unique(topo.face[topo.vertex_is_boundary[topo.origin]])] = True
    return out


@dataclass(frozen=True)
class Features:
    """Sharp edges, corners and the vertices whose sectors need the EP path.

    sharp: (e,) bool.  count: (n,) sharp edges per vertex.  corner: (n,) bool.
    sector_vertex: (n,) bool, vertices that take the EP path because of their tags (sectors,
    darts, corner tags without sharp edges) or an interior valence of 2.
    dart: (n,) bool, interior vertices with exactly one sharp edge."""

    sharp: np.ndarray
    count: np.ndarray
    corner: np.ndarray
    sector_vertex: np.ndarray
    dart: np.ndarray


def features(topo: Topology) -> Features:
    """Classify the mesh's vertices by their sharp edges (module docstring)."""
    sharp = sharp_edges(topo)
    n = topo.n_vertices
    ends = topo.edges[sharp]
    count = np.bincount(ends.ravel(), minlength=n)
    corner = corner_vertices(topo, sharp)
    dart = (count == 1) & ~topo.vertex_is_boundary
    # Sector sizes: around every vertex with sharp edges, walk the ring once per valence.
    needs = np.zeros(n, dtype=bool)
    candidates = np.flatnonzero((count > 0) | (corner & topo.vertex_is_used))
    for ring, boundary in topo.fans(candidates):
        vs = topo.origin[ring[:, 0]]
        spoke_sharp = sharp[topo.edge_of[ring]]
        if boundary:  # the incoming boundary edge closes the fan: one more sharp spoke
            spoke_sharp = np.concatenate([spoke_sharp, np.ones((len(vs), 1), dtype=bool)], axis=1)
        largest = _largest_sector(spoke_sharp, boundary)
        is_corner = corner[vs]
        needs[vs] = (largest >= 3) | (is_corner & (largest == 2)) | (largest == 0)
    # A corner tag on a vertex without sharp edges: one sector, the vertex interpolated; a
    # dart: one sector all round, no G1 across its sharp spoke; valence 2: two flat corners.
    needs |= corner & (count == 0) & topo.vertex_is_used
    needs |= dart
    needs |= (count == 0) & ~topo.vertex_is_boundary & (topo.valence == 2)
    if topo.mesh.interpolate_boundary == 0:  # boundary vertices bound no surface (no_surface)
        needs &= ~topo.vertex_is_boundary
    return Features(sharp, count, corner, needs, dart)


def _largest_sector(spoke_sharp: np.ndarray, boundary: bool) -> np.ndarray:
    """(E,) the most faces between two consecutive sharp spokes of a ring (n spokes, patch i
    between spoke i and i+1; a boundary ring's last patch is the gap).  0 when no spoke is sharp
    (a single sector without ends)."""
    e, n = spoke_sharp.shape
    patches = n - 1 if boundary else n
    # run length of non-sharp spokes before each spoke, cyclically (twice round is enough)
    doubled = np.concatenate([spoke_sharp, spoke_sharp], axis=1)
    run = np.zeros(e, dtype=np.int64)
    best = np.zeros(e, dtype=np.int64)
    for i in range(2 * n):
        run = np.where(doubled[:, i], 0, run + 1)
        if not boundary or i < n:
            best = np.maximum(best, np.where(doubled[:, i], 0, run))
    sizes = best + 1  # faces in a sector = interior spokes + 1
    sizes = np.minimum(sizes, patches)
    return np.where(spoke_sharp.any(axis=1), sizes, 0)


def refuse_singular_rings(topo: Topology, feats: Features, eps: np.ndarray, forced: np.ndarray) -> None:
    """Refuse (UnsupportedError naming it) a valence-4 vertex forced through the EP path
    (``force_extraordinary``, a check of the construction) when a spoke leads to another EP.

    Why: the angle configuration of a valence-4 ring is the regular one, with beta_i(0) = 0 on
    every spoke, so the G_1 equations at the vertex (section 3.4) read 5 alpha_A (f_i - s_i) +
    5 alpha_B (f_{i-1} - s_i) + b1_i (s_i - P00) = 0: a cyclic system in the four face points
    that is singular (for uniform intervals alpha_A = alpha_B: its alternating sum must
    vanish), and the terms b1_i of spokes ending at EPs break that condition (the vertex
    enclosure constraint).  With regular far ends b1 = 0 and it is solvable.  Corner-tagged
    smooth vertices of valence 4 avoid it with a skewed fan (``g1_patches.FOUR_FAN``)."""
    eps = np.asarray(eps, dtype=np.int64)
    is_ep = np.zeros(topo.n_vertices, dtype=bool)
    is_ep[eps] = True
    interpolated = feats.corner & (feats.count == 0)
    candidates = eps[(topo.valence[eps] == 4) & ~topo.vertex_is_boundary[eps] & np.isin(eps, forced) & ~interpolated[eps]]
    for v in candidates.tolist():
        ends = topo.dest[topo.one_ring(v)]
        if is_ep[ends].any():
            w = int(ends[is_ep[ends]][0])
            raise UnsupportedError(
                f"forcing the EP path at vertex {v} of valence 4 next to the extraordinary point {w}: "
                "the G1 conditions around it have no solution with the regular angles",
                topo.mesh.where("vertex", v),
            )
