"""Feature-adaptive refinement for semi-sharp creases.

``build_operator`` handles semi-sharp tags by ``N = ceil(s)`` *global* subdivision steps before
patching while the refined mesh stays small (1,024 faces, or with refinement="global" 6 steps
and 2M faces); beyond that (``operator._refinement``) it takes this module's patches instead,
with the T-junctions as split sides (``split_sides``): the pawn (588 faces, s = 6) would need
2.4 M faces, a 5 x 4 torus with one crease at s = 5 20,480 faces for 632 patches here.  Here
only the faces near what still needs the sharp rules are refined again.  Level 0 is the input
mesh; ``G_j`` is the global level-j mesh (``subdivision.subdivide(mesh, j)``), which is never
built: at level j only a *window* ``W_j``, a submesh of ``G_j``, is.  Its faces are

* the *domain* ``D_j``: the children of the faces refined at level j - 1 (``D_0``: all faces);
* a margin of rings around it, so that subdivision rules and patches, which are local, are
  computed as on ``G_j`` inside the domain (``MARGIN``; tests compare with ``G_j``).

A domain face is *refined* (``R_j``) when it lies within ``radius`` face rings of a *seed*
vertex (faces touching the vertex are ring 1); otherwise it is a *leaf* and gets the patch that
``build_operator`` gives it on ``G_j`` (built on a submesh of the window).  At level N nothing
is refined.  Seeds at level j:

* the ends of live semi-sharp edges (0 < s_j < 10, s_j = s - j as the subdivision carries it)
  and vertices with a corner tag;
* every vertex that is not *regular*: regular means interior, valence 4, quads only, no tag,
  no zero interval; or, when all of the input's intervals are equal, a regular crease vertex
  (interior valence 4 with two opposite infinitely sharp edges, or a boundary vertex of two
  quads under interpolateboundary 1 or 2).

Why the leaves are exact: a leaf at level j < N has no seed within ``radius`` (2) rings, so its
patch and the subdivision rules around it are those of a regular region, where the seed rules
are midpoint knot insertion (tested against OpenCASCADE in ``test_subdivision``) and, along a
regular crease with uniform knots, Catmull-Clark's boundary rules, whose limit is the bicubic
patch with mirrored phantom points (``bezier_extraction``).  So the level-N patches that the
global construction puts inside a leaf are its de Casteljau pieces at parameter 1/2, 1/4, ...;
the adaptive surface equals the global one pointwise (``tests/test_adaptive.py``).  EPs,
corners, darts, non-uniform creases and boundaries are seeds, so their neighbourhoods reach
level N, where the patches are the global construction's own (a coarse EP patch would be
another valid G1 surface, but not the same: the "coarse EP" variant is left for later).
Across a level transition, a coarse leaf side meets 2^k finer sides (T-junctions), all in a
regular region: the surface is C2 there.

Child numbering (``subdivision``): child face ``h`` of parent half-edge ``h`` =
``(V(origin h), E(edge h), F(face h), E(edge prev h))``.  So a face keeps a *global id* without
the global mesh: level-1 face of input face f, corner c: ``offsets[f] + c``; below, ``4 g + c``.
Child c covers the parent's parameter square corner c; parent side k is child k's side 0
(first half) followed by child (k+1)'s side 3 (second half)::

    parent corner c at C_c, side midpoints E_k;  child c: (s', t') -> C_c + s' (E_c - C_c) + t' (E_{c-1} - C_c)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from patching.bernstein import evaluate_nets
from patching.errors import UnsupportedError
from patching.topology.features import sharp_edges
from patching.mesh.control_mesh import INFINITELY_SHARP, ControlMesh
from patching.operator.assembly import assemble
from patching.operator.refinement import refinement_plan
from patching.operator.split_sides import adaptive_layout, split_side_topology
from patching.options import BuildOptions
from patching.subdivision.catmark import subdivision_operator
from patching.surface import CORNER_PARAMETERS, OperatorGroup, SurfaceOperator
from patching.topology.cache import remember, topology_of
from patching.topology.tables import Topology

__all__ = [
    "AdaptivePatches", "adaptive_operator", "adaptive_surface_operator", "global_steps", "child_parameters", "junction_residuals", "MAX_ADAPTIVE_STEPS",
]

#: Most adaptive levels (gregory_test7 needs 9).
MAX_ADAPTIVE_STEPS = 10
#: Rings (of the parent level) around the refined faces whose children form the next window:
#: the next domain then has about 2 MARGIN rings of margin, enough for the seed distances
#: (radius + 2), the leaves' patch submesh (PATCH_MARGIN) and the next step's rules.
MARGIN = 3
#: Rings around the leaves in the submesh their patches are built on.
PATCH_MARGIN = 4
#: Depth (rings from the window's cut) below which a parent face's children are trusted.
RULE_DEPTH = 3


def global_steps(mesh: ControlMesh, topology: Topology | None = None) -> int:
    """N: ceil of the largest finite sharpness (edges and corners), or 1 for a mesh with
    non-quad faces and no semi-sharp tag, 0 otherwise: the steps ``build_operator`` takes
    (read from ``refinement.refinement_plan`` itself, so the two cannot drift apart)."""
    return refinement_plan(topology or Topology(mesh))[0]


@dataclass
class _Level:
    """The window at level j.

    mesh, topo: the window (a submesh of G_j).  gid: (f,) global level-j face ids.
    rows: (n, n0) CSR, the window's points on the input's control points.
    real_boundary: (h,) bool, half-edges on the real (not cut) boundary.
    status: (f,) int8, 0 margin, 1 leaf, 2 refined.  patch: (f,) int64 patch index of leaves (-1).
    """

    mesh: ControlMesh
    topo: Topology
    gid: np.ndarray
    rows: sp.csr_matrix
    real_boundary: np.ndarray
    status: np.ndarray = field(default=None)
    patch: np.ndarray = field(default=None)

    def local_faces(self, gids: np.ndarray) -> np.ndarray:
        """Window faces of global ids (-1 where not in the window)."""
        gids = np.asarray(gids, dtype=np.int64)
        if self.gid.size == 0:
            return np.full(gids.shape, -1, dtype=np.int64)
        if not hasattr(self, "_order"):
            self._order = np.argsort(self.gid, kind="stable")
        ranked = self.gid[self._order]
        at = np.minimum(np.searchsorted(ranked, gids), ranked.size - 1)
        return np.where(ranked[at] == gids, self._order[at], -1)


@dataclass(frozen=True)
class AdaptivePatches:
    """Leaf patches of the adaptive hierarchy, on the input's control points.

    matrix: (rows, n0) CSR; patch p owns rows ``row_offset[p] + i (d+1) + j`` for net[i, j].
    level, face, degree, row_offset: (p,) int64; ``face`` is the global level-``level`` face id.
    spans: (p, 2) float64, the knot intervals of each patch's face along s and t on its level's
        window (``Topology.face_spans``: halved at every level), which ``export.pack`` joins
        blocks of same-level patches with.
    junctions: (k, 6) float64 rows (coarse patch, coarse side, fine patch, fine side, u0, u1):
        the fine side covers [u0, u1] of the coarse side's parameter (in the coarse side's
        direction, 0..1) and runs the other way (u = u1 - w (u1 - u0)); one row per pair of
        sides that meet, same-level pairs included (u0 = 0, u1 = 1, listed once).
    steps: N.  stats: per level (domain, refined, leaves, window faces, patch-submesh faces).
    """

    matrix: sp.csr_matrix
    level: np.ndarray
    face: np.ndarray
    degree: np.ndarray
    row_offset: np.ndarray
    junctions: np.ndarray
    steps: int
    stats: tuple
    spans: np.ndarray | None = None

    @property
    def n_patches(self) -> int:
        """Number of leaf patches."""
        return int(self.level.size)

    def nets(self, points: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """{degree: (patch ids (k,), nets (k, d+1, d+1, 3))} for control points (n0, 3)."""
        coeffs = self.matrix @ np.asarray(points, dtype=np.float64)
        out = {}
        for d in np.unique(self.degree).tolist():
            ids = np.flatnonzero(self.degree == d)
            rows = self.row_offset[ids][:, None] + np.arange((d + 1) ** 2)[None, :]
            out[d] = (ids, coeffs[rows].reshape(-1, d + 1, d + 1, 3))
        return out


# ------------------------------------------------------------------------------------------
# Rings of faces


def _incidence(topo: Topology) -> sp.csr_matrix:
    """(faces, vertices) 0/1 CSR."""
    return sp.csr_matrix(
        (np.ones(topo.origin.size), (topo.face, topo.origin)), shape=(topo.n_faces, topo.n_vertices)
    )


def _face_rings(inc: sp.csr_matrix, start_vertices: np.ndarray, limit: int) -> np.ndarray:
    """(f,) int64: 1 for faces touching a start vertex, k for faces sharing a vertex with a
    face of ring k - 1; limit + 1 beyond ``limit`` rings."""
    dist = np.full(inc.shape[0], limit + 1, dtype=np.int64)
    verts = start_vertices.astype(np.float64)
    incT = inc.T.tocsr()
    for k in range(1, limit + 1):
        faces = (inc @ verts) > 0
        dist[faces & (dist > k)] = k
        verts = (incT @ faces.astype(np.float64)) > 0
    return dist


def _grow(inc: sp.csr_matrix, faces: np.ndarray, rings: int) -> np.ndarray:
    """(f,) bool: faces within ``rings`` rings of a face in ``faces`` (0 rings: the faces)."""
    if rings == 0:
        return faces.copy()
    verts = (inc.T @ faces.astype(np.float64)) > 0
    return _face_rings(inc, verts, rings) <= rings


def _unpinch(topo: Topology, faces: np.ndarray) -> np.ndarray:
    """Add the whole fan of every vertex where the chosen faces form two or more fans (a
    submesh must stay manifold)."""
    faces = faces.copy()
    inc = None
    while True:
        sel = faces[topo.face]
        tw = topo.twin
        pred = np.where(tw >= 0, topo.next[np.maximum(tw, 0)], -1)
        start = sel & ((pred < 0) | ~faces[topo.face[np.maximum(pred, 0)]])
        starts = np.bincount(topo.origin[start], minlength=topo.n_vertices)
        pinched = starts >= 2
        if not pinched.any():
            return faces
        inc = inc if inc is not None else _incidence(topo)
        faces |= (inc @ pinched.astype(np.float64)) > 0


def _submesh(mesh: ControlMesh, topo: Topology, faces: np.ndarray, clear_semi_sharp: bool = False):
    """The faces ``faces`` (bool) of ``mesh`` as a ControlMesh with its intervals (one per strip
    of the submesh, taken from the parent), creases, corners and holes.

    Returns (submesh, its Topology, face ids in the parent, vertex ids in the parent,
    half-edge ids in the parent); the Topology is also the one ``topology_of(submesh)`` gives."""
    fid = np.flatnonzero(faces)
    offsets = mesh.face_offsets
    sizes = offsets[fid + 1] - offsets[fid]
    sub_offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    he = np.repeat(offsets[fid] - sub_offsets[:-1], sizes) + np.arange(sub_offsets[-1])
    vid, local = np.unique(topo.origin[he], return_inverse=True)
    bare = ControlMesh(
        vertices=mesh.vertices[vid],
        face_vertices=local.astype(np.int64),
        face_offsets=sub_offsets,
        interpolate_boundary=mesh.interpolate_boundary,
        name=mesh.name,
    )
    st = Topology(bare)
    parent_edge = topo.edge_of[he[st.edge_halfedge]]
    d = topo.edge_interval[parent_edge]
    first = np.full(st.n_strips, -1, np.int64)
    first[st.edge_strip[::-1]] = np.arange(st.n_edges)[::-1]
    intervals = {(int(st.edges[e, 0]), int(st.edges[e, 1])): float(d[e]) for e in first.tolist()}
    s = topo.edge_sharpness[parent_edge]
    keep = (s >= INFINITELY_SHARP) if clear_semi_sharp else (s > 0)
    creases = {(int(st.edges[e, 0]), int(st.edges[e, 1])): float(s[e]) for e in np.flatnonzero(keep).tolist()}
    new_id = np.full(mesh.n_vertices, -1, np.int64)
    new_id[vid] = np.arange(vid.size)
    corners = {
        int(new_id[v]): float(c)
        for v, c in mesh.corners.items()
        if new_id[v] >= 0 and (c >= INFINITELY_SHARP or not clear_semi_sharp)
    }
    face_new = np.full(mesh.n_faces, -1, np.int64)
    face_new[fid] = np.arange(fid.size)
    holes = frozenset(int(face_new[f]) for f in mesh.holes if face_new[f] >= 0)
    sub = replace(bare, intervals=intervals, creases=creases, corners=corners, holes=holes)
    sub_topo = remember(sub, st.retagged(sub))  # the subdivision step of the next level asks for it
    return sub, sub_topo, fid, vid, he


# ------------------------------------------------------------------------------------------
# Seeds: what needs level N


def _uniform(topo: Topology) -> bool:
    """True when every edge has one and the same positive knot interval.  Read on the edges,
    not on the tags: a strip without a tag keeps the default 1, so tags that all say 2 still
    make the knots non-uniform."""
    d = topo.edge_interval
    return bool(d.size == 0 or (d.min() == d.max() and d[0] > 0))


def _seed_vertices(topo: Topology, uniform: bool) -> np.ndarray:
    """(n,) bool: vertices within whose rings the sharp rules or irregular patches act (module
    docstring): live semi-sharp ends, corner tags, and every vertex that is not regular."""
    mesh = topo.mesh
    n = topo.n_vertices
    es = topo.edge_sharpness
    live = (es > 0) & (es < INFINITELY_SHARP)
    seed = np.zeros(n, dtype=bool)
    seed[topo.edges[live].ravel()] = True
    seed[list(mesh.corners.keys())] = True
    sharp = sharp_edges(topo)
    count = np.bincount(topo.edges[sharp].ravel(), minlength=n)
    quad_face = np.diff(mesh.face_offsets) == 4
    all_quads = np.ones(n, dtype=bool)
    np.logical_and.at(all_quads, topo.origin, quad_face[topo.face])
    zero = np.zeros(n, dtype=bool)
    zero[topo.edges[topo.edge_interval == 0].ravel()] = True
    boundary = topo.vertex_is_boundary
    smooth = ~boundary & (topo.valence == 4) & (count == 0)
    # Two opposite sharp spokes at an interior valence-4 vertex: h and rotate(rotate(h)).
    h = np.arange(topo.origin.size)
    h2 = topo.rotate(topo.rotate(h))
    opposite = np.zeros(n, dtype=bool)
    ok = h2 >= 0
    opposite[topo.origin[h[ok]]] |= sharp[topo.edge_of[h[ok]]] & sharp[topo.edge_of[h2[ok]]]
    crease = uniform & ~boundary & (topo.valence == 4) & (count == 2) & opposite
    border = uniform & boundary & (mesh.interpolate_boundary in (1, 2)) & (topo.valence == 3) & (count == 2)
    regular = (smooth | crease | border) & all_quads & ~zero
    seed |= topo.vertex_is_used & ~regular
    return seed


# ------------------------------------------------------------------------------------------
# The hierarchy


def _child_gid(level_index: int, mesh0: ControlMesh, gid: np.ndarray, corner: np.ndarray) -> np.ndarray:
    """Global id of child ``corner`` of global face ``gid`` at level ``level_index``."""
    if level_index == 0:
        return mesh0.face_offsets[gid] + corner
    return 4 * gid + corner


def adaptive_operator(
    mesh: ControlMesh,
    radius: int = 2,
    options: BuildOptions = BuildOptions(),
    keep_levels: bool = False,
) -> AdaptivePatches | tuple[AdaptivePatches, list[_Level]]:
    """The adaptive patches of ``mesh`` (module docstring): leaves refined near seeds only.

    radius: face rings around the seeds refined at each level.  2 is the least that is exact:
    a leaf then has no seed among its 4 x 4 control points, and the faces beside it none at
    their corners, so its patch and the rules that refine its neighbourhood are regular ones;
    with 1 the tests find leaves that differ from the global surface.  Returns AdaptivePatches, and with
    keep_levels=True also the list of windows (``_Level``) for tests.
    Raises UnsupportedError beyond MAX_ADAPTIVE_STEPS levels, and whatever
    ``subdivision_operator`` / ``assembly.assemble`` raise on the windows.
    """
    topo = Topology(mesh)
    steps = global_steps(mesh, topo)
    if steps > MAX_ADAPTIVE_STEPS:
        raise UnsupportedError(f"sharpness needs {steps} adaptive levels; at most {MAX_ADAPTIVE_STEPS} are done", mesh.name)
    # Zero strips: the windows build (their runs of 2^j zero strips are knot insertion, not
    # tears, so the windows skip ``refusals``), but the patches of several levels do not close
    # up (torus 12 x 10, one zero strip, s = 7: no solid, 2,560 free edges).
    zero = np.flatnonzero(topo.edge_interval == 0)
    if zero.size:
        a, b = (int(x) for x in topo.edges[zero[0]])
        raise UnsupportedError(
            f"knot interval 0 on edge {a}-{b}: zero knot intervals are not supported yet on the "
            f"adaptive path (semi-sharp features refined {steps} levels)",
            mesh.where("interval", (min(a, b), max(a, b))),
        )
    uniform = _uniform(topo)
    n0 = mesh.n_vertices
    lev = _Level(mesh, topo, np.arange(mesh.n_faces), sp.identity(n0, format="csr"), topo.twin < 0)
    domain = np.ones(mesh.n_faces, dtype=bool)
    levels, blocks, meta, stats = [], [], [], []
    n_patches = 0
    for j in range(steps + 1):
        topo = lev.topo
        inc = _incidence(topo)
        cut = np.zeros(topo.n_vertices, dtype=bool)
        cut_he = (topo.twin < 0) & ~lev.real_boundary
        cut[topo.origin[cut_he]] = True
        cut[topo.dest[cut_he]] = True
        depth = _face_rings(inc, cut, radius + PATCH_MARGIN + 2)
        if np.any(domain & (depth <= max(radius + 1, PATCH_MARGIN))):
            raise AssertionError(f"level {j}: the window's margin is too thin (a bug)")
        if j < steps:
            seed = _seed_vertices(topo, uniform) & ~cut
            near = _face_rings(inc, seed, radius) <= radius
            refine = domain & near if (j > 0 or mesh.is_quad_mesh) else domain.copy()
            if np.any(near & ~domain & (depth > radius + 1)):
                raise AssertionError(f"level {j}: a face outside the domain needs refinement (a bug)")
        else:
            refine = np.zeros(topo.n_faces, dtype=bool)
        leaves = domain & ~refine
        lev.status = np.where(refine, 2, np.where(leaves, 1, 0)).astype(np.int8)
        lev.patch = np.full(topo.n_faces, -1, dtype=np.int64)
        n_patch_faces = 0
        if leaves.any():
            chosen = _unpinch(topo, _grow(inc, leaves, PATCH_MARGIN))
            sub, sub_topo, fid, vid, _ = _submesh(lev.mesh, topo, chosen, clear_semi_sharp=True)
            n_patch_faces = sub.n_faces
            op = assemble(sub, sub_topo, options)
            on_points = lev.rows[vid]
            for g in op.groups:
                window_face = fid[g.faces]
                pick = np.flatnonzero(leaves[window_face])
                if pick.size == 0:
                    continue
                d1 = (g.degree + 1) ** 2
                rows = (g.row_offset + d1 * pick[:, None] + np.arange(d1)[None, :]).ravel()
                blocks.append((op.matrix[rows] @ on_points).tocsr())
                faces_here = window_face[pick]
                lev.patch[faces_here] = n_patches + np.arange(pick.size)
                n_patches += pick.size
                meta.append((np.full(pick.size, j), lev.gid[faces_here], np.full(pick.size, g.degree), topo.face_spans[faces_here]))
        stats.append((int(domain.sum()), int(refine.sum()), int(leaves.sum()), topo.n_faces, n_patch_faces))
        levels.append(lev)
        if j == steps:
            break
        # Next window: the children of the faces within MARGIN rings of the refined ones.
        parents = _grow(inc, refine, MARGIN)
        if np.any(parents & (depth <= RULE_DEPTH)):
            raise AssertionError(f"level {j}: refined faces too close to the window's cut (a bug)")
        s_step, child = subdivision_operator(lev.mesh, rules="seed", crease_method="uniform")
        offsets = lev.mesh.face_offsets
        child_faces = np.zeros(child.n_faces, dtype=bool)
        child_faces[np.flatnonzero(parents[topo.face])] = True  # child face h of parent half-edge h
        ctopo = topology_of(child)  # derived from the window's tables (``subdivision.child_topology``)
        child_faces = _unpinch(ctopo, child_faces)
        sub, sub_topo, fid, vid, he = _submesh(child, ctopo, child_faces)
        parent_he = fid  # child face id = parent half-edge id
        parent_face = topo.face[parent_he]
        corner = parent_he - offsets[parent_face]
        gid = _child_gid(j, mesh, lev.gid[parent_face], corner)
        # Real boundary: child half-edge 4 h + 0 halves parent half-edge h, 4 h + 3 halves prev(h).
        local_corner = he - 4 * fid.repeat(4)
        ph = parent_he.repeat(4)
        real = np.where(local_corner == 0, lev.real_boundary[ph], np.where(local_corner == 3, lev.real_boundary[topo.prev[ph]], False))
        rows = (s_step[vid] @ lev.rows).tocsr()
        next_domain = refine[parent_face]
        lev_next = _Level(sub, sub_topo, gid, rows, real)
        lev_next.real_boundary = real & (lev_next.topo.twin < 0)
        if not keep_levels:
            lev.rows = None
        lev, domain = lev_next, next_domain
    matrix = sp.vstack(blocks, format="csr") if blocks else sp.csr_matrix((0, n0))
    level = np.concatenate([m[0] for m in meta]).astype(np.int64) if meta else np.zeros(0, np.int64)
    face = np.concatenate([m[1] for m in meta]).astype(np.int64) if meta else np.zeros(0, np.int64)
    degree = np.concatenate([m[2] for m in meta]).astype(np.int64) if meta else np.zeros(0, np.int64)
    spans = np.concatenate([m[3] for m in meta]).astype(np.float64) if meta else np.zeros((0, 2))
    row_offset = np.concatenate([[0], np.cumsum((degree + 1) ** 2)[:-1]]).astype(np.int64)
    junctions = _junctions(levels, mesh)
    result = AdaptivePatches(matrix, level, face, degree, row_offset, junctions, steps, tuple(stats), spans)
    return (result, levels) if keep_levels else result


def _junctions(levels: list[_Level], mesh0: ControlMesh) -> np.ndarray:
    """Pairs of leaf sides that meet (AdaptivePatches.junctions): per level, the leaf sides
    facing a leaf of the same level (once per pair), then those facing a refined face, each
    followed by the leaf pieces along the refined face's side (``_pieces_along``)."""
    out = []
    for j, lev in enumerate(levels):
        topo = lev.topo
        leaf_faces = np.flatnonzero(lev.status == 1)
        if leaf_faces.size == 0:
            continue
        offsets = topo.mesh.face_offsets
        h = (offsets[leaf_faces][:, None] + np.arange(4)[None, :]).ravel()
        t = topo.twin[h]
        h, t = h[t >= 0], t[t >= 0]
        f, g = topo.face[h], topo.face[t]
        side_f, side_g = h - offsets[f], t - offsets[g]
        same = (lev.status[g] == 1) & (h < t)
        same &= (lev.patch[f] >= 0) & (lev.patch[g] >= 0)
        ones = np.ones(int(same.sum()))
        out.append(np.stack([lev.patch[f[same]], side_f[same], lev.patch[g[same]], side_g[same], 0 * ones, ones], axis=1))
        down = (lev.status[g] == 2) & (lev.patch[f] >= 0)
        out.append(_pieces_along(levels, mesh0, j, lev.patch[f[down]], side_f[down], lev.gid[g[down]], side_g[down]))
    return np.concatenate(out).astype(np.float64).reshape(-1, 6) if out else np.zeros((0, 6))


def _pieces_along(
    levels: list[_Level], mesh0: ControlMesh, j: int, patch: np.ndarray, side: np.ndarray, gid: np.ndarray, gside: np.ndarray
) -> np.ndarray:
    """(k, 6) junction rows (patch, side, fine patch, fine side, u0, u1) of leaf sides ``side``
    of ``patch`` (level j) facing side ``gside`` of the refined level-j faces ``gid``: the
    refined face's side is halved level by level (its corner ``gside`` child's side 0 takes
    [a, mid], the next corner's child's side 3 [mid, b]) down to leaves; the rows of one leaf
    side come in order along the refined side, and u runs against it on the coarse side
    (u_f = 1 - u_g).  Vectorised over all pieces of a level."""
    n = patch.size
    which, at_lo, pg, sg, at_hi = [], [], [], [], []
    owner, a, b = np.arange(n), np.zeros(n), np.ones(n)
    k = j
    while owner.size:
        nxt = levels[k + 1]
        mid = 0.5 * (a + b)
        owner = np.repeat(owner, 2)
        corner = np.stack([gside, (gside + 1) % 4], axis=1).ravel()
        child_side = np.tile([0, 3], gid.size)
        lo, hi = np.stack([a, mid], axis=1).ravel(), np.stack([mid, b], axis=1).ravel()
        cg = _child_gid(k, mesh0, np.repeat(gid, 2), corner)
        f = nxt.local_faces(cg)
        status = np.where(f >= 0, nxt.status[np.maximum(f, 0)], 0)
        if np.any(status == 0):
            raise AssertionError("a refined face's child is missing from the next domain (a bug)")
        leaf = (status == 1) & (nxt.patch[f] >= 0)
        which.append(owner[leaf])
        at_lo.append(lo[leaf])
        at_hi.append(hi[leaf])
        pg.append(nxt.patch[f[leaf]])
        sg.append(child_side[leaf])
        go = status == 2
        owner, gid, gside, a, b = owner[go], cg[go], child_side[go], lo[go], hi[go]
        k += 1
    if not which:
        return np.zeros((0, 6))
    which, at_lo, at_hi, pg, sg = (np.concatenate(x) for x in (which, at_lo, at_hi, pg, sg))
    order = np.lexsort((at_lo, which))  # per leaf side, along the refined side
    which, at_lo, at_hi, pg, sg = which[order], at_lo[order], at_hi[order], pg[order], sg[order]
    return np.stack([patch[which], side[which], pg, sg, 1.0 - at_hi, 1.0 - at_lo], axis=1)


def child_parameters(corner: int, s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parent parameters of child ``corner``'s (s, t) (module docstring)."""
    c = CORNER_PARAMETERS[corner]
    e_next = 0.5 * (CORNER_PARAMETERS[corner] + CORNER_PARAMETERS[(corner + 1) % 4])
    e_prev = 0.5 * (CORNER_PARAMETERS[corner] + CORNER_PARAMETERS[(corner - 1) % 4])
    p = c[None, :] + np.asarray(s)[:, None] * (e_next - c)[None, :] + np.asarray(t)[:, None] * (e_prev - c)[None, :]
    return p[:, 0], p[:, 1]


def junction_residuals(patches: AdaptivePatches, points: np.ndarray, samples: int = 9) -> tuple[float, float]:
    """Largest gap (absolute) and normal angle (radians) between the two sides of every
    junction whose patches differ in level, at ``samples`` points along each fine side."""
    nets = patches.nets(points)
    where = {}
    for d, (ids, _) in nets.items():
        for k, p in enumerate(ids.tolist()):
            where[p] = (d, k)
    rows = patches.junctions[patches.level[patches.junctions[:, 0].astype(int)] != patches.level[patches.junctions[:, 2].astype(int)]]
    w = np.linspace(0.0, 1.0, samples)
    gap, angle = 0.0, 0.0

    def side(p, k, u):
        d, i = where[int(p)]
        c0, c1 = CORNER_PARAMETERS[int(k)], CORNER_PARAMETERS[(int(k) + 1) % 4]
        st = c0[None] + u[:, None] * (c1 - c0)[None]
        x, ds, dt = evaluate_nets(nets[d][1][i : i + 1], st[:, 0], st[:, 1], derivatives=True)
        n = np.cross(ds[0], dt[0])
        return x[0], n / np.linalg.norm(n, axis=-1, keepdims=True)

    for pc, kc, pf, kf, u0, u1 in rows:
        xa, na = side(pc, kc, u0 + w * (u1 - u0))
        xb, nb = side(pf, kf, w[::-1])
        gap = max(gap, float(np.linalg.norm(xa - xb, axis=1).max()))
        angle = max(angle, float(np.arctan2(np.linalg.norm(np.cross(na, nb), axis=1), np.sum(na * nb, axis=1)).max()))
    return gap, angle


def adaptive_surface_operator(mesh: ControlMesh, options: BuildOptions) -> SurfaceOperator:
    """M of the feature-adaptive refinement (``adaptive.adaptive_operator``): rows grouped by
    degree, the patch topology with split sides at the T-junctions (``split_sides``).  A
    patch's face id is its first descendant on the finest level (the ids a global refinement
    of that many steps would give it)."""
    patches = adaptive_operator(mesh, options=options)
    order, table = adaptive_layout(patches)
    blocks, groups, offset = [], [], 0
    for d in np.unique(patches.degree[order]).tolist():
        ids = order[patches.degree[order] == d]
        rows = (patches.row_offset[ids][:, None] + np.arange((d + 1) ** 2)[None, :]).ravel()
        blocks.append(patches.matrix[rows])
        faces = patches.face[ids] * 4 ** (patches.steps - patches.level[ids])
        groups.append(OperatorGroup(int(d), faces.astype(np.int64), offset, patches.spans[ids]))
        offset += rows.size
    matrix = sp.vstack(blocks).tocsr()
    return SurfaceOperator(matrix, tuple(groups), split_side_topology(order.size, table), mesh.name)
