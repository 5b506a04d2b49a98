"""The linear operator from control points to Bézier coefficients (DESIGN 3).

``SurfaceOperator.matrix`` is a scipy.sparse CSR matrix M with one column per control point and
one row per Bézier coefficient: coefficients = M @ P (``parallel.product``: the same product,
its row blocks on several cores).  It is built from topology, knot
intervals and tags only, never from positions, so moving control points costs one sparse
product.  Rows come in groups of one degree; inside a group, patch k of bi-degree d owns rows
``offset + k (d+1)^2 + i (d+1) + j`` for its coefficient net[i, j] (see ``surface``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .anchor_fairing import faired_anchors
from .auxiliary_points import anchor_matrix
from .bernstein import elevation_matrix_2d
from .blas import one_blas_thread
from .bezier_extraction import cubic_extraction, regular_face_points
from .cluster_fairing import ClusterFairing, ep_clusters
from .errors import KnotError, MeshError, UnsupportedError
from .features import Features, faces_without_surface, features, refuse_singular_rings, sharp_edges
from .g1_patches import G1Assembly, RowMixer, ep_groups
from .mesh import ControlMesh
from .parallel import product
from .patch_topology import patch_topology
from .surface import BezierSurface, PatchGroup, PatchTopology
from .topology import Topology

__all__ = ["SurfaceOperator", "build_operator", "build", "patched_mesh", "ANCHOR_RULES", "INTERIOR_RULES", "G1_SOLVES", "REFINEMENTS"]

#: Placements of the auxiliary control points (``build_operator(anchors=...)``).
ANCHOR_RULES = ("eigen-polyhedron", "extraction", "faired")
#: Rules for the four inner ("blue") coefficients of a quintic patch (``build_operator(interior=...)``).
INTERIOR_RULES = ("extraction", "cubic-isocurves")
#: How the G1 unknowns are set (``build_operator(g1_solve=...)``).
G1_SOLVES = ("joint", "seed")


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
        return product(self.matrix, np.asarray(points, dtype=np.float64))

    def evaluate(self, points: np.ndarray) -> BezierSurface:
        """The patches for control points (n, 3)."""
        from .validation import as_points, check_points, used_size

        points = as_points(points, "points", rows=self.matrix.shape[1])
        check_points(points, self.used_points, self.topology.is_closed, self.name)
        coeffs = self.coefficients(points)
        groups = []
        for g in self.groups:
            d = g.degree
            block = coeffs[g.row_offset : g.row_offset + g.n_rows].reshape(-1, d + 1, d + 1, 3)
            groups.append(PatchGroup(d, g.faces, block))
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


@one_blas_thread
def build_operator(
    mesh: ControlMesh,
    topology: Topology | None = None,
    angles: str = "optimized",
    force_extraordinary: Sequence[int] = (),
    anchors: str = "eigen-polyhedron",
    interior: str = "extraction",
    g1_solve: str = "joint",
    *,
    refinement: str = "auto",
    _refined: bool = False,
) -> SurfaceOperator:
    """Build M for a closed polygon mesh: bicubic patches on regular faces, G1 bi-quintic
    patches on faces touching extraordinary points (seed 002, section 3); a mesh with
    non-quad faces is first subdivided once (``subdivision``), and M includes that step.

    angles: the angle configuration at EPs, "optimized" (seed 002 section 3.3, default),
    "default" (the heuristic angles) or "uniform" (2 pi / n, the baseline of [32]).
    anchors: placement of the auxiliary control points, "eigen-polyhedron" (section 3.5,
    default), "extraction" (``auxiliary_points``) or "faired" (``anchor_fairing``).
    interior: the four inner coefficients P[2..3, 2..3] of every quintic patch, which no G1
    condition reads.  "extraction" (default) keeps them at the degree-elevated extraction,
    the nearest values to it, as the red and green steps choose theirs; "cubic-isocurves" is
    seed 002's explicit rule (f_1, f_2: iso-curves as cubic as possible, ``g1_patches.blue``).
    Deviation from the seed, measured (issue 6 note; tests/test_blending_quality.py): the
    seed's rule carries the G1 corrections of rows 0-1 linearly into the interior, where they
    meet the unchanged rows 4-5 and can leave a ripple near the far side of the patch.  Over
    benchmarks/blending.py's 200 random configurations a row (valence 5 and 6) both rules give
    every blending function one maximum at interval ratio 5; at ratio 20 "extraction" gives
    100.0% and 100.0%, the seed's rule 99.8% and 99.5%.  The surfaces are as fair (thin-plate
    energy 0.81 to 1.03 times the seed rule's on the OpenSubdiv shapes), and the build skips
    a step.
    g1_solve: "joint" (default) solves the G1 unknowns of every cluster of EPs joined by
    spokes at once, minimising the thin-plate energy under all the cluster's G1 conditions
    (``cluster_fairing``: ours, it removes folds the per-EP order makes); "seed" keeps seed
    002's per-EP and per-spoke steps everywhere.  Isolated EPs get the seed's steps either way.
    refinement: how semi-sharp tags are refined before patching (``_refinement``): "auto"
    (default) takes the feature-adaptive path (``adaptive``: the same surface, far fewer
    patches, T-junctions as split sides) wherever the global steps would make more than
    MAX_AUTO_GLOBAL_FACES faces and the adaptive path can go; "global" refines the whole mesh
    while that fits (MAX_SEMI_SHARP_STEPS, MAX_REFINED_FACES), so that the patches cover the
    faces of one mesh (``patched_mesh``), as ``export.pack`` needs.
    topology: the mesh's Topology if already built.
    """
    from .validation import check_build_arguments  # NupatchError naming the argument

    check_build_arguments(mesh, angles=angles, anchors=anchors, interior=interior, g1_solve=g1_solve,
                          refinement=refinement, topology=topology)
    topo = topology or Topology(mesh)
    if not _refined:
        # Tears are judged on the user's mesh, before any refinement: refining a zero strip
        # inserts its knot again (two halves of interval 0), so the refined mesh shows runs of
        # 2^k zero strips where the surface is the input's (_refuse_torn_knots).
        _refuse_torn_knots(topo)
        _refuse_tiny_intervals(topo)
        _refuse_zero_strips_between_creases(topo)
    # Seed 002 patches smooth quads.  Semi-sharp creases and corners (0 < s < 10) first take
    # ceil(s) steps of the sharp subdivision rules, after which every sharpness is 0; non-quad
    # faces take one step, which turns every polygon into quads (issue 4).  Done globally when
    # the refined mesh is small, else adaptively (``adaptive``: refined only near the
    # features, the same surface, patches of several levels meeting at T-junctions;
    # ``_refinement`` says when).  M of the refined mesh times the steps' S acts on the
    # original control points; regular quad regions keep their surface (a step there is knot
    # insertion).
    steps, adaptive = _refinement(topo, refinement)
    if adaptive:
        return _adaptive_operator(mesh, angles, anchors, interior, g1_solve)
    if steps:
        from .subdivision import subdivision_operator

        composed = sp.identity(mesh.n_vertices, format="csr")
        refined = mesh
        for _ in range(steps):
            step, refined = subdivision_operator(refined, rules="seed")
            composed = (step @ composed).tocsr()
        inner = build_operator(refined, angles=angles, anchors=anchors, interior=interior, g1_solve=g1_solve, _refined=True)
        return SurfaceOperator(product(inner.matrix, composed), inner.groups, inner.topology, mesh.name)
    feats = features(topo)
    spans = face_spans(topo)
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
    if quintic_faces.size:
        groups_ep = ep_groups(topo, eps, feats)
        g1 = G1Assembly(topo, groups_ep, face_row, angles)
        # Compose the row mixings first (few entries per row), then apply them once to the
        # elevated rows and the extraction: cheaper than a pass over the longer elevated rows
        # per step (serial, half-EP mesh, where red alone sets most rows: 0.13 s against 0.16 s).
        clusters = ep_clusters(groups_ep, topo) if g1_solve == "joint" else []
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
        groups.append(OperatorGroup(5, quintic_faces, n_cubic_rows))
        rule = "eigen-polyhedron" if anchors == "faired" else anchors
        smooth_groups = [g for g in groups_ep if g.theta is None]
        anchor_rows = anchor_matrix(topo, smooth_groups, extraction.anchor_column, n, rule=rule)
        anchor_rows = anchor_rows + _sector_anchors(topo, feats, groups_ep, extraction.anchor_column, n)
    else:
        anchor_rows = sp.csr_matrix((n_anchor, n))
    if patchless.size:
        mixing = mixing[: n_rows - 36 * patchless.size]
    # Anchors folded in by one product with [I; anchors] (cheaper than slicing the columns
    # apart and adding two long matrices); each row block goes through both products at once.
    if anchors != "faired" or not n_anchor:
        matrix = product(mixing, extraction.nets, _with_anchors(anchor_rows), prune=True)
    else:
        stacked = product(mixing, extraction.nets).tocsr()  # rows over [control points | anchors]
        degrees = np.concatenate([np.full(len(g.faces), g.degree) for g in groups])
        patch_faces = np.concatenate([g.faces for g in groups])
        sets = [extraction.anchor_column[g.h[e]] - n for g in smooth_groups for e in range(len(g.vertices))]
        anchor_rows = faired_anchors(stacked, n, anchor_rows, sets, degrees, spans[patch_faces])
        matrix = product(stacked, _with_anchors(anchor_rows), prune=True)
    ordered = np.concatenate([g.faces for g in groups])
    ptopo = patch_topology(topo, ordered, spans)
    return SurfaceOperator(matrix, tuple(g for g in groups if len(g.faces)), ptopo, mesh.name)


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


#: Ways to refine semi-sharp tags before patching (``build_operator(refinement=...)``).
REFINEMENTS = ("auto", "global")
#: Most global subdivision steps (and faces after them) spent on semi-sharp features before
#: patching; beyond them the refinement is adaptive whatever ``refinement`` says.
MAX_SEMI_SHARP_STEPS = 6
MAX_REFINED_FACES = 2_000_000
#: Under refinement="auto", the most faces the global steps may make before the adaptive path
#: takes over.  Measured (benchmarks/semi_sharp.py): from about 1,000 global faces on, the
#: adaptive path always gave fewer patches (1.5x on a 96-face cube with a semi-sharp loop at
#: s = 2, 5x on a 5 x 4 torus with one crease at s = 3, 32x at s = 5); below, it saves at
#: most 2.5x (a 6-face cube at s = 2 or 3: the same 96 or 384; the torus at s = 2: 320 against
#: 152 to 272) and no time to STEP (1.8 to 2.1 s on either path, mostly OCC's fixed cost).
MAX_AUTO_GLOBAL_FACES = 1024


def _semi_sharp_steps(topo: Topology) -> int:
    """ceil of the largest finite sharpness below 10 on edges and corners (0 if none)."""
    mesh = topo.mesh
    values = np.concatenate([topo.edge_sharpness, np.array(list(mesh.corners.values()), dtype=np.float64)])
    semi = values[(values > 0) & (values < 10)]
    return int(np.ceil(semi.max())) if semi.size else 0


def _refinement(topo: Topology, refinement: str = "auto") -> tuple[int, bool]:
    """(steps, adaptive): the subdivision steps taken before patching (semi-sharp tags, or one
    for n-gons), and whether they are taken adaptively (``adaptive``) rather than globally.

    Adaptive when the global steps would not fit (more than MAX_SEMI_SHARP_STEPS steps or
    MAX_REFINED_FACES faces), and under refinement="auto" also when they would make more than
    MAX_AUTO_GLOBAL_FACES faces, unless the adaptive path cannot go or gains nothing: a zero
    knot interval anywhere (``adaptive_operator`` refuses them), or no semi-sharp tag (the one
    step for n-gons refines every face on either path).  ValueError for another refinement."""
    if refinement not in REFINEMENTS:
        raise ValueError(f"refinement must be one of {REFINEMENTS}, not {refinement!r}")
    mesh = topo.mesh
    semi = _semi_sharp_steps(topo)
    steps = semi or (0 if mesh.is_quad_mesh else 1)
    faces = mesh.n_faces * 4**steps  # the faces after the global steps (n-gons counted as quads)
    if steps == 0:
        return 0, False
    if steps > MAX_SEMI_SHARP_STEPS or faces > MAX_REFINED_FACES:
        return steps, True
    auto = refinement == "auto" and semi > 0 and faces > MAX_AUTO_GLOBAL_FACES
    return steps, bool(auto and np.all(topo.edge_interval > 0))


def patched_mesh(mesh: ControlMesh, refinement: str = "auto") -> ControlMesh:
    """The all-quad mesh whose faces the patches of ``build_operator(mesh, refinement=...)``
    cover: the mesh itself, or after the global subdivision steps taken for semi-sharp tags
    and n-gons (its positions those steps' refinement of the control points).  Refused
    (UnsupportedError) where the refinement is adaptive: there patches of several levels
    cover the faces."""
    steps, adaptive = _refinement(Topology(mesh), refinement)
    if adaptive:
        raise UnsupportedError(f"{mesh.name} is refined adaptively: its patches cover faces of several levels", mesh.name)
    from .subdivision import subdivision_operator

    points = mesh.vertices
    for _ in range(steps):
        step, mesh = subdivision_operator(mesh, rules="seed")
        points = step @ points
    return mesh.with_positions(points) if steps else mesh


def _adaptive_operator(mesh: ControlMesh, angles: str, anchors: str, interior: str, g1_solve: str) -> SurfaceOperator:
    """M of the feature-adaptive refinement (``adaptive.adaptive_operator``): rows grouped by
    degree, the patch topology with split sides at the T-junctions (``split_sides``).  A
    patch's face id is its first descendant on the finest level (the ids a global refinement
    of that many steps would give it)."""
    from .adaptive import adaptive_operator
    from .split_sides import adaptive_layout, split_side_topology

    patches = adaptive_operator(mesh, angles=angles, anchors=anchors, interior=interior, g1_solve=g1_solve)
    order, table = adaptive_layout(patches)
    blocks, groups, offset = [], [], 0
    for d in np.unique(patches.degree[order]).tolist():
        ids = order[patches.degree[order] == d]
        rows = (patches.row_offset[ids][:, None] + np.arange((d + 1) ** 2)[None, :]).ravel()
        blocks.append(patches.matrix[rows])
        faces = patches.face[ids] * 4 ** (patches.steps - patches.level[ids])
        groups.append(OperatorGroup(int(d), faces.astype(np.int64), offset))
        offset += rows.size
    matrix = sp.vstack(blocks).tocsr()
    return SurfaceOperator(matrix, tuple(groups), split_side_topology(order.size, table), mesh.name)


def _refuse_torn_knots(topo: Topology) -> None:
    """Three zero intervals in a row inside the user's mesh make an interior knot of
    multiplicity 4: a cubic B-spline is discontinuous there for generic control points, so no
    closed surface exists (KnotError naming the input's edge).

    Judged on the input only (``build_operator`` skips it on its own refinements): a
    subdivision step halves every interval, so one zero strip becomes two, then four; that is
    knot insertion of the same knot value, which leaves the surface unchanged (the refined
    control points coincide across the run), not a tear.  Quads only: a zero strip cannot
    cross a triangle or n-gon (unequal intervals around it are refused, and equal zero ones put
    zero spokes at the new extraordinary point)."""
    mesh = topo.mesh
    quad = mesh.face_sizes == 4
    base = mesh.face_offsets[:-1]
    iv = topo.halfedge_interval
    spans = face_spans(topo)
    for direction, (side_a, side_b) in enumerate(((1, 3), (0, 2))):
        zero = quad & (spans[:, direction] == 0)
        ta = np.where(quad, topo.twin[np.where(quad, base + side_a, 0)], -1)
        tb = np.where(quad, topo.twin[np.where(quad, base + side_b, 0)], -1)
        inside = (ta >= 0) & (tb >= 0)
        width_a = np.where(ta >= 0, iv[topo.next[np.maximum(ta, 0)]], 1.0)
        width_b = np.where(tb >= 0, iv[topo.next[np.maximum(tb, 0)]], 1.0)
        torn = np.flatnonzero(zero & inside & (width_a == 0) & (width_b == 0))
        if torn.size:
            f = int(torn[0])
            h = int(base[f] + (0 if direction == 0 else 1))
            a, b = int(topo.origin[h]), int(topo.dest[h])
            raise KnotError(
                f"three zero knot intervals in a row around face {f} (edge {a}-{b}): an interior "
                "knot of multiplicity 4 tears the surface",
                mesh.where("interval", (min(a, b), max(a, b))),
            )


#: Smallest nonzero knot interval, relative to the largest: the patches of a strip that much
#: narrower than the others are far thinner than the B-rep tolerance (1e-7 of the size), and
#: from about 1e-300 their coefficients overflow (inf, nan).
TINY_INTERVAL_RATIO = 1e-12


def _refuse_tiny_intervals(topo: Topology) -> None:
    """KnotError naming the user's tag when a nonzero interval is below TINY_INTERVAL_RATIO of
    the largest (0 is the multiple knot the user may have meant)."""
    iv = topo.halfedge_interval
    positive = iv[iv > 0]
    if positive.size == 0 or positive.min() >= TINY_INTERVAL_RATIO * positive.max():
        return
    d, largest = float(positive.min()), float(positive.max())
    mesh = topo.mesh
    tagged = [key for key, value in mesh.intervals.items() if value == d]
    h = int(np.flatnonzero(iv == d)[0])
    key = tagged[0] if tagged else tuple(sorted((int(topo.origin[h]), int(topo.dest[h]))))
    raise KnotError(
        f"knot interval {d:.3g} of edge {key[0]}-{key[1]} is below {TINY_INTERVAL_RATIO:g} of the largest ({largest:.3g}): "
        "its patches would be thinner than the tolerance; give 0 for a multiple knot",
        mesh.where("interval", key),
    )


def _refuse_zero_strips_between_creases(topo: Topology) -> None:
    """A zero strip (one or more in a row) between two infinitely sharp interior edges: the
    strip's faces collapse (no patch, their two long sides one B-rep edge), but the patches on
    either side end on two different crease curves, so the surface tears there (before: an
    invalid B-rep, BrepError).  The intervals' eps -> 0 limit keeps a patch of no parametric
    width spanning the two curves, which this version does not build: UnsupportedError naming
    the user's zero edge and the two creases.  One crease beside the strip is the eps limit."""
    mesh = topo.mesh
    quad = mesh.face_sizes == 4
    base = mesh.face_offsets[:-1]
    spans = face_spans(topo)
    zero_u = np.flatnonzero(quad & (spans[:, 0] == 0) & (spans[:, 1] > 0))
    zero_v = np.flatnonzero(quad & (spans[:, 1] == 0) & (spans[:, 0] > 0))
    if zero_u.size + zero_v.size == 0:
        return
    e = topo.edge_of
    # zero in u: the long sides h1 and h3 collapse onto one edge; zero in v: h0 and h2
    links = np.concatenate([base[zero_u] + 1, base[zero_v]]), np.concatenate([base[zero_u] + 3, base[zero_v] + 2])
    graph = sp.coo_matrix((np.ones(links[0].size), (e[links[0]], e[links[1]])), shape=(topo.n_edges,) * 2)
    edge_class = connected_components(graph, directed=False)[1]
    creased = np.flatnonzero(sharp_edges(topo) & ~topo.edge_is_boundary)
    classes, first, count = np.unique(edge_class[creased], return_index=True, return_counts=True)
    if not (count > 1).any():
        return
    k = int(np.flatnonzero(count > 1)[0])
    c1 = int(creased[first[k]])
    c2 = int(creased[edge_class[creased] == classes[k]][1])
    faces = np.concatenate([zero_u, zero_v])
    f = int(faces[edge_class[e[links[0]]] == classes[k]][0])
    h = int(base[f] + (0 if f in set(zero_u.tolist()) else 1))  # an edge of the zero interval
    a, b = int(topo.origin[h]), int(topo.dest[h])
    (p, q), (r, t) = (tuple(int(x) for x in topo.edges[c]) for c in (c1, c2))
    raise UnsupportedError(
        f"knot interval 0 on edge {a}-{b} between the infinitely sharp creases {p}-{q} and {r}-{t}: "
        "the zero strip would tear the surface between the two crease curves (not supported yet)",
        mesh.where("interval", (min(a, b), max(a, b))),
    )


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


def face_spans(topo: Topology) -> np.ndarray:
    """(f, 2) float64: the face's knot interval in u (edges h0, h2) and in v (h1, h3).

    Zero in either direction: zero parametric area, no patch (issue 3)."""
    base = topo.mesh.face_offsets[:-1]
    return np.stack([topo.halfedge_interval[base], topo.halfedge_interval[base + 1]], axis=1)


def build(
    mesh: ControlMesh,
    angles: str = "optimized",
    anchors: str = "eigen-polyhedron",
    interior: str = "extraction",
    g1_solve: str = "joint",
    *,
    refinement: str = "auto",
) -> BezierSurface:
    """The patched surface of a mesh: ``build_operator(mesh, ...).evaluate(mesh.vertices)``
    (refinement="global" for ``export.pack``, which needs the patches of one mesh).

    MeshError when no face gives a patch (holes, interpolateboundary 0, zero intervals): an
    empty surface is no solid or shell, and nothing the exporters could write."""
    surface = build_operator(
        mesh, angles=angles, anchors=anchors, interior=interior, g1_solve=g1_solve, refinement=refinement
    ).evaluate(mesh.vertices)
    if surface.n_patches == 0:
        causes = [f"{len(mesh.holes)} of {mesh.n_faces} faces are holes"] if mesh.holes else []
        if mesh.interpolate_boundary == 0:
            causes.append("interpolateboundary 0 drops every face at the open boundary")
        if any(d == 0.0 for d in mesh.intervals.values()):
            causes.append("zero knot intervals leave faces of no parametric area")
        raise MeshError(f"no face gives a patch, the surface is empty ({'; '.join(causes) or 'no face has a patch'})", mesh.name)
    return surface
