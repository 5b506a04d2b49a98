"""Bicubic Bézier extraction with auxiliary anchors ([FSLYJ] sec. 3.2, Figs. 6-7, eqs. 1-3).

Every corner of every quad face (a half-edge h: the corner origin(h) of face(h)) gets a *face
point* FP[h], the interior Bézier point of that face nearest that corner.  Edge points and
vertex points are weighted averages of face points of neighbouring faces, and the 16 bicubic
coefficients of a face are its 4 face points, 8 edge points and 4 vertex points:

    net[i, j] (i along h0, j along -h3)      V3 -- E(h2,v3) -- E(h2,v2) -- V2
                                             |                             |
                                          E(h3,v3)  FP[h3]      FP[h2]  E(h1,v2)
                                             |                             |
                                          E(h3,v0)  FP[h0]      FP[h1]  E(h1,v1)
                                             |                             |
                                             V0 -- E(h0,v0) -- E(h0,v1) -- V1

All weights are affine combinations (rows sum to one) of mesh control points and *anchors*:
an extraordinary point (EP) of valence n is replaced by n anchors, one per face around it,
which stand for the face points at the EP ([FSLYJ] Fig. 5).  Anchor columns follow the
control-point columns; ``anchor_column[h]`` names the anchor of corner h.

Face points on a face whose corners are all regular are the double-knot-insertion points
(Fig. 6a): with the face's intervals delta (along h0) and epsilon (along h1) and the widths W_k
of the neighbouring faces across side k,

    alpha_0 = W_3 / (W_3 + delta + W_1),  alpha_1 = (W_3 + delta) / (W_3 + delta + W_1)

(gamma likewise with W_0, epsilon, W_2), FP = bilinear interpolation of the four corners at
(alpha_a, gamma_b).  A face with EP corners (Fig. 7) keeps the anchor at each EP corner; the
other face points are written through the anchors so that they never need an interval "beyond"
an EP.  Reconstruction (the printed gamma of Fig. 7a is garbled, the gammas of eq. 2 have the
wrong sign): in one direction the double-knot points satisfy X_1 = c X_0 + (1 - c) e_1 with
c = (1 - alpha_1) / (1 - alpha_0) = W_far / (delta + W_far), which involves no interval beyond
the near corner.  Applying it in one direction gives the one-neighbour rule (F_0, F_2 of
Fig. 7a), in both directions the opposite-corner rule (F_1 of Fig. 7a, the tensor product);
between two EP neighbours the average of the two one-direction rules (eq. 2, with the weights
adding up to one and F_2 using its own corner P_3, as the figure's symmetry requires).  Check:
replacing every anchor by its regular face point reproduces the regular face points exactly
(tests/test_bezier_extraction.py), and every row sums to one.

Edge points (eq. 1): on the edge between faces F and G, near vertex v,
E = (W_G FP_F + W_F FP_G) / (W_F + W_G) with W the faces' widths across the edge.
Vertex points (eq. 3): V = sum_i w_i FP_i / sum_i w_i over the faces i around v, with
w_i = d_{i-1} d_{i+2} (spoke intervals; face i between spokes i and i+1).  At a valence-4
vertex this is the tensor-product vertex point; at an EP it is eq. (3) on the anchors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from patching.topology.tables import Topology
from patching.util.sparse_rows import TripletRows

__all__ = ["CubicExtraction", "cubic_extraction", "regular_face_points"]

# Local positions of the 16 coefficients, as (i, j) -> which point.
#: net position of the face point of corner k
FACE_POINT_POSITION = ((1, 1), (2, 1), (2, 2), (1, 2))
#: net position of the vertex point at corner k
VERTEX_POSITION = ((0, 0), (3, 0), (3, 3), (0, 3))
#: net positions of the edge points on side k: (near corner k, near corner k+1)
EDGE_POSITIONS = (((1, 0), (2, 0)), ((3, 1), (3, 2)), ((2, 3), (1, 3)), ((0, 2), (0, 1)))


def _safe_ratio(num: np.ndarray, den: np.ndarray, fallback: float = 0.5) -> np.ndarray:
    out = np.full(np.broadcast(num, den).shape, fallback, dtype=np.float64)
    ok = den > 0
    np.divide(num, den, out=out, where=ok)
    return out


@dataclass(frozen=True)
class CubicExtraction:
    """The C0 bicubic extraction of all quad faces.

    nets: sparse (16 f, n + a) rows over control points then anchors; face f owns rows
        16 f + 4 i + j for net[i, j].
    anchor_column: (h,) int64, the column of the anchor of corner h (-1 at regular corners).
    n_points, n_anchors: column counts.
    """

    nets: sp.csr_matrix
    anchor_column: np.ndarray
    n_points: int
    n_anchors: int


def _face_point_triplets(topo: Topology, is_ep: np.ndarray, anchor_column: np.ndarray, sharp_edge: np.ndarray) -> TripletRows:
    """The triplets of FP[h] for every half-edge h of every quad face."""
    offsets = topo.mesh.face_offsets
    base = offsets[:-1]
    h = base[:, None] + np.arange(4)[None, :]  # (f, 4) half-edges h_k
    iv = topo.halfedge_interval
    corner = topo.origin[h]  # (f, 4) vertex ids
    ep = is_ep[corner]  # (f, 4)
    I = iv[h]  # interval along side k
    twin = topo.twin[h]
    # Width of the neighbour across side k; across an infinitely sharp edge, and beyond an
    # open boundary, the face's own width (the mirrored neighbour of a crease: phantom row
    # P_-1 = 2 P_0 - P_1, the limit of the crease rules).  At a clamped side the face is in
    # the zero strip, so its own width across the boundary is 0: the clamped end's phantom
    # leg.  Under interpolateboundary 0 the mirror gives the faces one ring inside exactly
    # their patches of modes 1 and 2 (Catmull-Clark's, with uniform knots).
    W = np.where(twin >= 0, iv[topo.next[np.maximum(twin, 0)]], 0.0)
    across_sharp = sharp_edge[topo.edge_of[h]] | (twin < 0)
    own = np.roll(I, -1, axis=1)  # the face's width across side k is the interval of side k+1
    W = np.where(across_sharp, own, W)

    def col(k):  # (f,) column of plain corner k
        return corner[:, k % 4]

    def idx(k):
        return np.arange(4)[(k % 4)]

    triplets = TripletRows()

    def add(mask, target_k, column, weight):
        if np.any(mask):
            triplets.add(h[mask, target_k], column[mask], np.broadcast_to(weight, mask.shape)[mask])

    for k in range(4):
        kp, km, ko = (k + 1) % 4, (k + 3) % 4, (k + 2) % 4
        at_ep = ep[:, k]
        both = ~at_ep & ep[:, kp] & ep[:, km]
        one_next = ~at_ep & ep[:, kp] & ~ep[:, km]  # EP neighbour e = k+1 (shared side s = k)
        one_prev = ~at_ep & ep[:, km] & ~ep[:, kp]  # EP neighbour e = k-1 (shared side s = k-1)
        opposite = ~at_ep & ~ep[:, kp] & ~ep[:, km] & ep[:, ko]
        regular = ~at_ep & ~ep.any(axis=1)
        anchor_of = lambda j: anchor_column[h[:, j % 4]]  # noqa: E731

        # Anchor at an EP corner.
        add(at_ep, k, anchor_of(k), 1.0)

        # One EP neighbour: F_k = c A_e + (1 - c) [(1 - g) P_k + g P_m]  (Fig. 7a, F_0 / F_2).
        for mask, e, s, fside, m in (
            (one_next, kp, k, km, km),  # e = k+1: shared side k, far side k-1, other far corner k-1
            (one_prev, km, km, k, kp),  # e = k-1: shared side k-1, far side k, other far corner k+1
        ):
            c = _safe_ratio(W[:, fside], I[:, s] + W[:, fside])
            g = _safe_ratio(W[:, s], W[:, s] + I[:, fside] + W[:, (s + 2) % 4])
            add(mask, k, anchor_of(e), c)
            add(mask, k, col(k), (1 - c) * (1 - g))
            add(mask, k, col(m), (1 - c) * g)

        # Two EP neighbours: average of the two one-direction rules (eq. 2, corrected).
        c_a = _safe_ratio(W[:, km], I[:, k] + W[:, km])  # from e = k+1 along side k
        c_b = _safe_ratio(W[:, k], I[:, km] + W[:, k])  # from e = k-1 along side k-1
        add(both, k, anchor_of(kp), 0.5 * c_a)
        add(both, k, anchor_of(km), 0.5 * c_b)
        add(both, k, col(k), 1 - 0.5 * (c_a + c_b))

        # Opposite EP only: tensor product of the one-direction rule (Fig. 7a, F_1).
        e = ko
        cx = _safe_ratio(W[:, (e + 1) % 4], I[:, e] + W[:, (e + 1) % 4])
        cy = _safe_ratio(W[:, (e + 2) % 4], I[:, (e + 1) % 4] + W[:, (e + 2) % 4])
        g0 = _safe_ratio(W[:, e], W[:, e] + I[:, (e + 1) % 4] + W[:, (e + 2) % 4])
        a0 = _safe_ratio(W[:, (e + 3) % 4], W[:, (e + 3) % 4] + I[:, e] + W[:, (e + 1) % 4])
        add(opposite, k, anchor_of(e), cx * cy)
        add(opposite, k, col(e + 3), cx * (1 - cy) * (1 - a0))
        add(opposite, k, col(e + 1), (1 - cx) * cy * (1 - g0))
        add(opposite, k, col(k), cx * (1 - cy) * a0 + (1 - cx) * cy * g0 + (1 - cx) * (1 - cy))

        # Regular face: double knot insertion (Fig. 6a).
        a_, b_ = FACE_POINT_POSITION[k][0] - 1, FACE_POINT_POSITION[k][1] - 1  # 0/1 per direction
        alpha = _safe_ratio(W[:, 3] + a_ * I[:, 0], W[:, 3] + I[:, 0] + W[:, 1])
        gamma = _safe_ratio(W[:, 0] + b_ * I[:, 1], W[:, 0] + I[:, 1] + W[:, 2])
        add(regular, k, col(0), (1 - alpha) * (1 - gamma))
        add(regular, k, col(1), alpha * (1 - gamma))
        add(regular, k, col(2), alpha * gamma)
        add(regular, k, col(3), (1 - alpha) * gamma)
    return triplets


def _crease_neighbour_intervals(topo: Topology, hs: np.ndarray, sharp_edge: np.ndarray, corner_vertex: np.ndarray):
    """Intervals of the crease legs before origin(h) and after dest(h), for sharp half-edges hs.

    At a crease vertex (two sharp edges, no corner) the leg continues on the other sharp edge,
    whatever the valence (a crease through a regular vertex, through an EP, or an open boundary
    turning through a vertex with one face under interpolateboundary 2).  At a corner, or where
    a crease ends (a dart), the polygon ends: the leg is mirrored (h's own interval, the phantom
    point 2 P_0 - P_1), so the curve ends at the vertex."""
    iv = topo.halfedge_interval
    ends = topo.edges[sharp_edge]
    count = np.bincount(ends.ravel(), minlength=topo.n_vertices)
    total = np.bincount(ends.ravel(), weights=np.repeat(topo.edge_interval[sharp_edge], 2), minlength=topo.n_vertices)
    own = iv[hs]

    def leg(v):
        return np.where(corner_vertex[v] | (count[v] != 2), own, total[v] - own)

    return leg(topo.origin[hs]), leg(topo.dest[hs])


def regular_face_points(topo: Topology, sharp_edge: np.ndarray) -> sp.csr_matrix:
    """(h, n) the double-knot face point of every corner of every quad face (Fig. 6a), as if
    no vertex were extraordinary; across sharp edges the mirrored neighbour.  The anchors of a
    sector at a sharp vertex are these points (``operator``)."""
    none = np.zeros(topo.n_vertices, dtype=bool)
    no_anchor = np.full(topo.origin.size, -1, dtype=np.int64)
    return _face_point_triplets(topo, none, no_anchor, sharp_edge).matrix((topo.origin.size, topo.n_vertices))


def cubic_extraction(
    topo: Topology,
    is_ep: np.ndarray | None = None,
    sharp_edge: np.ndarray | None = None,
    corner_vertex: np.ndarray | None = None,
) -> CubicExtraction:
    """C0 bicubic extraction of every quad face of an all-quad mesh (module docstring).

    is_ep: (n,) bool, the vertices replaced by anchors (default: the topology's EPs).
    sharp_edge: (e,) bool, infinitely sharp edges (default none; ``features``).  Across them the faces read a mirrored neighbour; their edge
    and vertex points are those of the crease polygon's own cubic B-spline (its strip
    intervals), so both sides end exactly on the crease curve, C0.  Boundary edges are passed
    here as sharp when the boundary is interpolated.
    corner_vertex: (n,) bool, corners (interpolated: the vertex point is the control point).
    Faces need their four sides interior for edge points and their corners interior for
    vertex points; rows of other faces are left incomplete and must not be used.
    """
    n = topo.n_vertices
    n_he = topo.origin.size
    if is_ep is None:
        is_ep = np.zeros(n, dtype=bool)
        is_ep[topo.extraordinary] = True
    ep_corner = is_ep[topo.origin]
    anchor_column = np.full(n_he, -1, dtype=np.int64)
    n_anchors = int(np.count_nonzero(ep_corner))
    anchor_column[ep_corner] = n + np.arange(n_anchors)
    columns = n + n_anchors

    if sharp_edge is None:
        sharp_edge = np.zeros(topo.n_edges, dtype=bool)
    if corner_vertex is None:
        corner_vertex = np.zeros(n, dtype=bool)
    fp = _face_point_triplets(topo, is_ep, anchor_column, sharp_edge).matrix((n_he, columns))

    iv = topo.halfedge_interval
    twin = topo.twin
    sharp_he = sharp_edge[topo.edge_of]
    inner = np.flatnonzero((twin >= 0) & ~sharp_he)
    other = topo.next[twin[inner]]  # the neighbour's corner at origin(h)
    w_f = iv[topo.next[inner]]  # width of face(h) across edge(h)
    w_g = iv[other]  # width of the neighbour across edge(h)
    share = _safe_ratio(w_g, w_f + w_g)
    edge_w = sp.csr_matrix(
        (np.concatenate([share, 1 - share]), (np.concatenate([inner, inner]), np.concatenate([inner, other]))),
        shape=(n_he, n_he),
    )
    # Crease edge points: the leg points of the crease polygon (1D double knot insertion with
    # the intervals of the crease before origin(h), of h, and after dest(h)).  Open boundaries
    # are creases too (interpolateboundary 1, 2): there a leg point near the far end is also
    # needed, as no twin provides it.  At a corner the crease polygon ends: the leg before it
    # is mirrored (the phantom point 2 P_0 - P_1), so the curve ends at the corner point.
    hs = np.flatnonzero(sharp_he)
    interval_before, interval_after = _crease_neighbour_intervals(topo, hs, sharp_edge, corner_vertex)
    d = iv[hs]
    total = interval_before + d + interval_after
    a = _safe_ratio(interval_before, total)
    b = _safe_ratio(interval_before + d, total)
    ends = (np.concatenate([hs, hs]), np.concatenate([topo.origin[hs], topo.dest[hs]]))
    crease_near_origin = sp.csr_matrix((np.concatenate([1 - a, a]), ends), shape=(n_he, columns))
    crease_near_dest = sp.csr_matrix((np.concatenate([1 - b, b]), ends), shape=(n_he, columns))
    edge_rows = (edge_w @ fp + crease_near_origin).tocsr()
    # Vertex points: w_h = d(spoke before) * d(spoke after next), spokes in rotation order.
    before = np.where(twin >= 0, topo.next[np.maximum(twin, 0)], -1)  # spoke i-1 of corner h
    after = topo.twin[topo.prev]  # spoke i+1
    after2 = np.where(after >= 0, topo.twin[topo.prev[np.maximum(after, 0)]], -1)  # spoke i+2
    interior_corner = ~topo.vertex_is_boundary[topo.origin] & (before >= 0) & (after2 >= 0)
    hv = np.flatnonzero(interior_corner)
    weight = iv[before[hv]] * iv[after2[hv]]
    total_w = np.bincount(topo.origin[hv], weights=weight, minlength=n)
    count = np.bincount(topo.origin[hv], minlength=n)
    vw = _safe_ratio(weight, total_w[topo.origin[hv]], fallback=0.0)
    degenerate = total_w[topo.origin[hv]] <= 0
    vw[degenerate] = 1.0 / count[topo.origin[hv]][degenerate]
    # Vertices on a crease (two or more sharp edges) take the crease rule; a dart (one sharp
    # edge) keeps the smooth vertex point ([TLC] sec. 4: the crease fades out there).
    on_crease = np.bincount(topo.edges[sharp_edge].ravel(), minlength=n) >= 2
    keep = ~on_crease[topo.origin[hv]] & ~corner_vertex[topo.origin[hv]]
    vertex_w = sp.csr_matrix((vw[keep], (topo.origin[hv][keep], hv[keep])), shape=(n, n_he))
    # At a crease vertex: the crease B-spline's vertex point from its two leg points near it,
    # each weighted by the other leg's interval; a corner keeps its control point.
    lone = hs[twin[hs] < 0]  # boundary legs also end at their dest
    leg_vertex = np.concatenate([topo.origin[hs], topo.dest[lone]])
    leg_row = np.concatenate([hs, n_he + lone])  # rows of [crease near origin; near dest]
    leg_d = np.concatenate([d, iv[lone]])
    corner = corner_vertex[leg_vertex] | ~on_crease[leg_vertex]
    leg_vertex, leg_row, leg_d = leg_vertex[~corner], leg_row[~corner], leg_d[~corner]
    leg_total = np.bincount(leg_vertex, weights=leg_d, minlength=n)
    cw = _safe_ratio(leg_total[leg_vertex] - leg_d, leg_total[leg_vertex])
    crease_vertex = sp.csr_matrix((cw, (leg_vertex, leg_row)), shape=(n, 2 * n_he))
    legs = sp.vstack([edge_rows, crease_near_dest]).tocsr()
    corners = np.flatnonzero(corner_vertex)
    corner_rows = sp.csr_matrix((np.ones(corners.size), (corners, corners)), shape=(n, columns))
    vertex_rows = vertex_w @ fp + crease_vertex @ legs + corner_rows

    # Stack [FP; EP; V] and select the 16 rows of every face.
    stack = sp.vstack([fp, edge_rows, vertex_rows, crease_near_dest]).tocsr()
    base = topo.mesh.face_offsets[:-1]
    f = base.size
    sel = np.zeros((f, 4, 4), dtype=np.int64)
    for k in range(4):
        hk = base + k
        i, j = FACE_POINT_POSITION[k]
        sel[:, i, j] = hk
        i, j = VERTEX_POSITION[k]
        sel[:, i, j] = 2 * n_he + topo.origin[hk]
        (i0, j0), (i1, j1) = EDGE_POSITIONS[k]
        sel[:, i0, j0] = n_he + hk
        # near corner k+1: the twin's point near its origin, or on an open boundary the
        # crease leg point near dest (rows after the vertex points)
        sel[:, i1, j1] = np.where(twin[hk] >= 0, n_he + np.maximum(twin[hk], 0), 2 * n_he + n + hk)
    nets = stack[sel.ravel()]
    return CubicExtraction(nets.tocsr(), anchor_column, n, n_anchors)
