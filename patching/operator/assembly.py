"""Assembly of M for an all-quad mesh without semi-sharp tags ([FSLYJ] sec. 3).

``SurfaceOperator.matrix`` (``surface``) is a scipy.sparse CSR matrix M with one column per
control point and one row per Bézier coefficient: coefficients = M @ P.  It is built from
topology, knot intervals and tags only, never from positions, so moving control points costs
one sparse product.  Rows come in groups of one degree; inside a group, patch k of bi-degree d
owns rows ``offset + k (d+1)^2 + i (d+1) + j`` for its coefficient net[i, j] (see ``surface``).

The stages, each a sparse factor: the bicubic extraction with auxiliary anchors
([FSLYJ] sec. 3.2, ``extraordinary.extraction``), degree elevation of the faces at EPs, the G1
row mixings ([FSLYJ] sec. 3.4, ``extraordinary.g1_patches`` and ``cluster_fairing``), and the
anchors as combinations of control points ([FSLYJ] sec. 3.5), folded in by one product.
Refinement (semi-sharp tags, n-gons) happens before, in ``refinement`` and ``adaptive``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.sparse as sp

from patching.bernstein import elevation_matrix_2d
from patching.errors import UnsupportedError
from patching.extraordinary.anchor_fairing import faired_anchors
from patching.extraordinary.auxiliary_points import anchor_matrix
from patching.extraordinary.cluster_fairing import ClusterFairing, ep_clusters
from patching.extraordinary.extraction import cubic_extraction, regular_face_points
from patching.extraordinary.g1_patches import G1Assembly, RowMixer, ep_groups
from patching.extraordinary.t_spline import ANCHOR_RULE as T_SPLINE_ANCHORS
from patching.extraordinary.t_spline import ANGLES as T_SPLINE_ANGLES
from patching.extraordinary.t_spline import t_spline_clusters
from patching.extraordinary.limit_fit import fitted_anchors
from patching.mesh.control_mesh import ControlMesh
from patching.options import BuildOptions
from patching.surface import OperatorGroup, SurfaceOperator
from patching.topology.features import Features, faces_without_surface, features, refuse_singular_rings
from patching.topology.patch_topology import patch_topology
from patching.topology.tables import Topology
from patching.util.parallel import product

__all__ = ["assemble"]


def assemble(
    mesh: ControlMesh, topo: Topology, options: BuildOptions, force_extraordinary: Sequence[int] = ()
) -> SurfaceOperator:
    """M of an all-quad mesh whose sharpnesses are 0 or infinite: bicubic patches on regular
    faces, G1 bi-quintic patches on faces touching extraordinary points ([FSLYJ] sec. 3),
    sectors between infinitely sharp edges as in [FSLYJ] sec. 4.2.  ``force_extraordinary``:
    interior vertices to treat as EPs whatever their valence (tests, comparisons)."""
    angles, anchors, interior, g1_solve = options.angles, options.anchors, options.interior, options.g1_solve
    t_spline = options.method == "t-spline"  # [SSEL13]'s construction (extraordinary.t_spline)
    if t_spline:
        angles = T_SPLINE_ANGLES
    feats = features(topo)
    spans = topo.face_spans
    # Hole faces (OpenSubdiv's `t hole`) and, under interpolateboundary 0, faces at the open
    # boundary give no patch; their control points still shape the faces around them, whose
    # rules do not change (features.faces_without_surface).
    has_patch = np.all(spans > 0, axis=1) & ~faces_without_surface(topo)
    faces = np.flatnonzero(has_patch)
    # EPs: smooth interior vertices of valence != 4, and vertices whose sectors between sharp
    # edges need anchors (features); corners and crease vertices whose fans the bicubic
    # construction reproduces are not EPs, whatever their valence.
    smooth = (feats.count == 0) & ~feats.corner
    forced = np.asarray(force_extraordinary, dtype=np.int64)
    eps = np.union1d(np.union1d(topo.extraordinary[smooth[topo.extraordinary]], forced), np.flatnonzero(feats.sector_vertex))
    if topo.vertex_is_boundary[forced].any():
        v = int(forced[topo.vertex_is_boundary[forced]][0])
        raise UnsupportedError(f"vertex {v} is on a boundary: it cannot be forced extraordinary", mesh.where("vertex", v))
    _refuse_degenerate_eps(topo, eps)
    refuse_singular_rings(topo, feats, eps, forced)
    is_ep = np.zeros(topo.n_vertices, dtype=bool)
    is_ep[eps] = True
    extraction = cubic_extraction(topo, is_ep, sharp_edge=feats.sharp, corner_vertex=feats.corner)
    n, n_anchor = extraction.n_points, extraction.n_anchors
    irregular_face = is_ep[mesh.quads()].any(axis=1)
    cubic_faces = faces[~irregular_face[faces]]
    quintic_faces = faces[irregular_face[faces]]
    groups = [OperatorGroup(3, cubic_faces, 0)]
    # One row space for the whole operator: the cubic faces' 16 rows, then 36 quintic rows per
    # irregular face, those without a patch (holes, zero spans: still read by the G1 steps
    # around their EPs) last, so that M's rows are a leading block of it.
    all_irregular = np.flatnonzero(irregular_face)
    patchless = np.setdiff1d(all_irregular, quintic_faces)
    quintic_order = np.concatenate([quintic_faces, patchless])
    n_cubic_rows = 16 * cubic_faces.size
    n_rows = n_cubic_rows + 36 * quintic_order.size
    face_row = np.full(mesh.n_faces, -1, dtype=np.int64)
    face_row[quintic_order] = n_cubic_rows + 36 * np.arange(quintic_order.size)
    # Start: the cubic faces' extraction rows as they are, the irregular faces' degree-elevated
    # (16 -> 36 rows); columns are rows of the extraction (16 f + 4 i + j).
    mixing = _select_and_elevate(cubic_faces, quintic_order, extraction.nets.shape[0])
    to_points = None  # extraction rows -> control points, once the anchor rows are known
    if quintic_faces.size:
        groups_ep = ep_groups(topo, eps, feats)
        g1 = G1Assembly(topo, groups_ep, face_row, angles)
        # Compose the row mixings first (few entries per row), then apply them once to the
        # elevated rows and the extraction: cheaper than a pass over the longer elevated rows
        # per step (serial, half-EP mesh, where red alone sets most rows: 0.13 s against 0.16 s).
        rule = T_SPLINE_ANCHORS if t_spline else "eigen-polyhedron" if anchors in ("faired", "limit-fit") else anchors
        smooth_groups = [g for g in groups_ep if g.theta is None]
        anchor_rows = anchor_matrix(topo, smooth_groups, extraction.anchor_column, n, angles=options.eigen_angles, rule=rule)
        anchor_rows = anchor_rows + _sector_anchors(topo, feats, groups_ep, extraction.anchor_column, n)
        if not t_spline:  # the blending functions before the G1 steps (monotone spoke curves)
            elevated, to_points = mixing, _points_of_extraction(extraction.nets, anchor_rows)
            g1.reference = lambda rows: elevated[rows] @ to_points
        clusters = ep_clusters(groups_ep, topo) if g1_solve == "joint" else []
        if t_spline:
            clusters = t_spline_clusters(groups_ep, topo)
        if clusters:
            fairing = ClusterFairing(g1, clusters, has_patch)
            rest = g1.without(fairing.members())
            g1_steps = (rest.red, rest.black, rest.green, fairing.joint)
        else:
            g1_steps = (g1.red, g1.black, g1.green)
        g1_steps += (g1.blue,) if interior == "cubic-isocurves" else ()
        steps_composed = None
        for solve in g1_steps:
            mixer = RowMixer(n_rows)
            solve(mixer)
            step = mixer.matrix()
            steps_composed = step if steps_composed is None else product(step, steps_composed)
        mixing = product(steps_composed, mixing)
        # The steps are spent: their matrices (~100 MB on the half-EP mesh) are freed before the
        # final product, which then reuses their pages.  First touches of fresh memory were most
        # of a cold build's system time (docs/speed.md, "A cold build's system time").
        del steps_composed, step, mixer
        g1.reference = elevated = None
        groups.append(OperatorGroup(5, quintic_faces, n_cubic_rows))
    else:
        anchor_rows = sp.csr_matrix((n_anchor, n))
    if patchless.size:
        mixing = mixing[: n_rows - 36 * patchless.size]
    # The extraction and the anchors are first folded into one short factor (extraction rows ->
    # control points), then applied to the mixing's long rows in one product.
    if anchors not in ("faired", "limit-fit") or not n_anchor:
        if to_points is None:
            to_points = _points_of_extraction(extraction.nets, anchor_rows)
        matrix = product(mixing, to_points, prune=True)
    else:
        stacked = product(mixing, extraction.nets).tocsr()  # rows over [control points | anchors]
        degrees = np.concatenate([np.full(len(g.faces), g.degree) for g in groups])
        patch_faces = np.concatenate([g.faces for g in groups])
        sets = [extraction.anchor_column[g.h[e]] - n for g in smooth_groups for e in range(len(g.vertices))]
        if anchors == "faired":
            anchor_rows = faired_anchors(stacked, n, anchor_rows, sets, degrees, spans[patch_faces])
        else:
            rings = [g.faces[e] for g in smooth_groups for e in range(len(g.vertices))]
            anchor_rows = fitted_anchors(mesh, stacked, n, anchor_rows, sets, rings, patch_faces, degrees)
        matrix = product(stacked, _with_anchors(anchor_rows), prune=True)
    ordered = np.concatenate([g.faces for g in groups])
    ptopo = patch_topology(topo, ordered, spans)
    return SurfaceOperator(matrix, tuple(g for g in groups if len(g.faces)), ptopo, mesh.name)


def _points_of_extraction(nets: sp.csr_matrix, anchor_rows: sp.csr_matrix) -> sp.csr_matrix:
    """nets @ [I; anchor rows]: the extraction's rows over the control points alone, anchors
    folded in.  Folded before it meets the mixing, this short factor (16 rows a face, ~15
    entries a row on the half-EP mesh) makes M one product, mixing @ it, where
    (mixing @ nets) @ [I; anchors] built a long intermediate first (half-EP mesh: 0.27 s of CPU
    against 0.49 s; M the same to 1e-15 of its largest entry, the sums associated the other way)."""
    return (nets @ _with_anchors(anchor_rows)).tocsr()


def _with_anchors(anchor_rows: sp.csr_matrix) -> sp.csr_matrix:
    """[I; anchor rows]: columns [control points | anchors] -> control points."""
    return sp.vstack([sp.identity(anchor_rows.shape[1], format="csr"), anchor_rows], format="csr")


def _select_and_elevate(cubic_faces: np.ndarray, quintic_faces: np.ndarray, n_columns: int) -> sp.csr_matrix:
    """(16 c + 36 q, n_columns) CSR over extraction rows: row 16 k + r picks row r of cubic
    face k; the 36 rows of quintic face k are its 16 rows degree-elevated to bi-quintic."""
    elevate = sp.csr_matrix(elevation_matrix_2d(3, 5))
    per_face = elevate.nnz
    cubic_cols = (16 * cubic_faces[:, None] + np.arange(16)).ravel()
    quintic_cols = (16 * quintic_faces[:, None] + elevate.indices[None, :]).ravel()
    indices = np.concatenate([cubic_cols, quintic_cols])
    row_starts = cubic_cols.size + (per_face * np.arange(quintic_faces.size)[:, None] + elevate.indptr[None, :-1]).ravel()
    indptr = np.concatenate([np.arange(cubic_cols.size), row_starts, [indices.size]])
    data = np.concatenate([np.ones(cubic_cols.size), np.tile(elevate.data, quintic_faces.size)])
    return sp.csr_matrix((data, indices, indptr), shape=(cubic_cols.size + 36 * quintic_faces.size, n_columns))


def _sector_anchors(topo: Topology, feats: Features, groups, anchor_column: np.ndarray, n_points: int) -> sp.csr_matrix:
    """(n_anchors, n_points): the anchors of sector EPs (sharp spokes, boundary fans, corners),
    each its corner's double-knot face point with mirrored neighbours across sharp edges
    (``bezier_extraction.regular_face_points``).  Section 3.5's eigen-polyhedron rule is
    defined for whole rings only; for a sector the G1 solve's first stage fits the tangent
    plane through the pinned crease legs instead."""
    n_anchors = int(np.count_nonzero(anchor_column >= 0))
    corners = np.concatenate([g.outgoing.ravel() for g in groups if g.theta is not None] + [np.zeros(0, np.int64)])
    if corners.size == 0:
        return sp.csr_matrix((n_anchors, n_points))
    points = regular_face_points(topo, feats.sharp)[corners].tocoo()
    rows = anchor_column[corners][points.row] - n_points
    return sp.csr_matrix((points.data, (rows, points.col)), shape=(n_anchors, n_points))


def _refuse_degenerate_eps(topo: Topology, eps: np.ndarray) -> None:
    if eps.size == 0:
        return
    mesh = topo.mesh
    mask = np.isin(topo.origin, eps) & (topo.halfedge_interval == 0)
    if mask.any():
        h = int(np.flatnonzero(mask)[0])
        a, b = int(topo.origin[h]), int(topo.dest[h])
        raise UnsupportedError(
            f"knot interval 0 on edge {a}-{b}, a spoke of the extraordinary point {a}: "
            "zero intervals at extraordinary points are not supported yet",
            mesh.where("interval", (min(a, b), max(a, b))),
        )

