"""Subdivision shading with semi-sharp creases ([ZBK] secs. 2.2-3.5) for Loop and
Catmull-Clark, as sparse operators built once from topology and tags.

After ``levels`` steps (the geometry: ``points = geometry @ P``), every vertex of the refined
mesh gets one normal per *region* (the faces around it between two sharp edges, [ZBK]
sec. 3.4, Fig. 6; one region at smooth vertices and darts):

* ``N_S``, the subdivided normal field ([ZBK] sec. 2.2): at level 1 every region gets the
  average of its faces' normals (area-weighted: the sum of their cross-product normals,
  [ZBK] sec. 3.5 "the average of the surrounding face normals"); these are subdivided to level
  ``levels`` with the geometry's own stencils, linearly ([ZBK] sec. 2.3: linear, not
  spherical, averaging), starting at level 1 ([ZBK] sec. 2.3).  A stencil row of a child
  region reads, for each point p it weights, the normals of p's corners in the parent faces on
  the region's side (the faces of its corners), each with an equal share: across a sharp edge
  the two sides stay apart, and where a semi-sharp edge turns smooth (its sharpness ran out,
  [ZBK] sec. 3.2) the child has one region and reads both sides, so the normals join.
* ``N_L``, the limit normal of the region (``limit``: the true limit surface's).
* ``b``, the blend weight ([ZBK] sec. 2.3, the second variant of its ref. [4]): 1 at the
  extraordinary vertices of level 1 and at their 1-rings, 0 elsewhere, subdivided like the
  geometry to level ``levels``.  Extraordinary: valence other than 6 (Loop) or 4
  (Catmull-Clark) inside, other than 4 or 3 on a boundary.  Variant B ([ZBK] sec. 3.1, the
  default): sharp vertices (crease and corner rules at level 1: two or more sharp edges,
  boundary edges included, or a sharp vertex) get 0 and do not seed their ring; variant A:
  they are treated as smooth vertices.  Darts (one sharp edge) are smooth vertices by
  default (``darts="smooth"``, [ZBK] secs. 4.3 and 5: an extraordinary dart is treated as an
  extraordinary vertex, seeding 1); ``darts="sharp"`` treats them as sharp vertices when the
  blend weights are set ([ZBK] sec. 3.3, Figs. 5, 12, 13: under variant B they get 0 and seed
  nothing; under variant A sharp vertices are smooth ones, so the two treatments agree).
  Semi-sharp features ([ZBK] sec. 3.2, Fig. 4): a sharp vertex whose semi-sharp edges (or
  corner sharpness) run out is from then on "treated exactly as a smooth vertex": if
  extraordinary, it seeds 1 at itself and its 1-ring (variant B; ``b`` elsewhere kept) one
  level after its rule turned smooth, i.e. at level s + 1 for a crease of integer sharpness s
  (whose level-s rule is the first smooth one): Fig. 4 shows no blending on the s = 4 edges
  after 4 steps and blending at their extraordinary vertices after 5.  Reconstructed from the
  text and Fig. 4's caption (the paper does not say how the new 1s meet the subdivided b; here
  they replace it; a vertex that turns smooth at or before the seeding level is seeded there).  The
  normals' stencils are the geometry's either way (a dart's region is its whole ring).
* ``N_B = normalise((1 - b^p) N_L + b^p N_S)``, [ZBK] eq. (1), p = 1 by default.

Reconstructed where the text is silent or damaged: the level at which blending starts (level
1, as the normals); whether ``N_S`` and ``b`` are pushed to the limit with limit stencils
(not done: the level-``levels`` values are used, so that ``b = 0`` gives exactly ``N_L``);
the side rule for stencils at sharp vertices (above; [ZBK] sec. 3.4 only says the normals of
the two sides "should stay" apart).  Checks: the tests (unit length; ``N_L`` where b = 0; one
normal per side at sharp creases equal to that side's limit normal; ``N_L`` everywhere on a
mesh without sharp features and extraordinary vertices).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import UnsupportedError
from ..mesh import ControlMesh
from ..topology import Topology
from ..loop.cache import topology_of
from ..loop.limit import LimitMasks
from ..loop.stationary import cross, level_rules, regions_of
from .limit import SCHEMES, limit_masks

__all__ = ["ShadingOperator", "SubdividedMesh", "shading_operator", "subdivide_with_normals", "NORMAL_MODES", "VARIANTS",
           "DART_MODES"]

NORMAL_MODES = ("none", "limit", "shading")
VARIANTS = ("a", "b")
DART_MODES = ("smooth", "sharp")
MAX_SHADING_FACES = 4_000_000


@dataclass
class SubdividedMesh:
    """The refined mesh as arrays.  points (n, 3) float64; faces (f, k) int64 (hole faces
    left out); corner_normal (f, k) int64 index into normals, or None; normals (r, 3) unit
    float64 or None; blend (n,) the blend weights b (shading only)."""

    points: np.ndarray
    faces: np.ndarray
    corner_normal: np.ndarray | None
    normals: np.ndarray | None
    blend: np.ndarray | None = None


def _step(mesh: ControlMesh, scheme: str, rules: str, crease_method: str | None):
    """(S, child, parent face of every child corner)."""
    topo = topology_of(mesh)
    if scheme == "loop":
        from ..loop.refine import loop_operator

        S, child = loop_operator(mesh, crease_method)
        parent_face = np.arange(child.face_vertices.size) // 12
    else:
        from ..subdivision import subdivision_operator

        S, child = subdivision_operator(mesh, rules=rules, crease_method=crease_method)
        parent_face = topo.face[np.arange(child.face_vertices.size) // 4]
    return S, child, parent_face


def _regions(mesh: ControlMesh):
    topo = topology_of(mesh)
    _, rule = level_rules(mesh, topo)
    label, rv = regions_of(mesh)
    return topo, label, rv, rule


def region_operator(S: sp.csr_matrix, ptopo: Topology, plabel: np.ndarray, prv: np.ndarray,
                    clabel: np.ndarray, crv: np.ndarray, parent_face: np.ndarray) -> sp.csr_matrix:
    """T (child regions x parent regions): the geometry's stencils on per-region values
    (module docstring).  An entry (c, p, w) of S for child region r: w spread equally over
    the corners of p in the parent faces on r's side, each read as its region's value."""
    nfp = ptopo.n_faces
    nvp = ptopo.n_vertices
    nreg = np.bincount(prv, minlength=nvp)
    single = nreg == 1
    some = np.zeros(nvp, np.int64)
    some[ptopo.origin] = plabel  # the region of a vertex that has one
    M = S[crv].tocoo()
    r, p, w = M.row.astype(np.int64), M.col.astype(np.int64), M.data
    direct = single[p]
    rows = [r[direct]]
    cols = [some[p[direct]]]
    vals = [w[direct]]
    multi = np.flatnonzero(~direct)
    if multi.size:
        # corners of each vertex, grouped (CSR over origin)
        order = np.argsort(ptopo.origin, kind="stable")
        start = np.searchsorted(ptopo.origin[order], np.arange(nvp + 1))
        cnt = start[p[multi] + 1] - start[p[multi]]
        ent = np.repeat(np.arange(multi.size), cnt)
        off = np.arange(ent.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        hp = order[start[p[multi]][ent] + off]
        # the (child region, parent face) pairs of the regions involved: their sides
        involved = np.zeros(crv.size, bool)
        involved[r[multi]] = True
        hc = np.flatnonzero(involved[clabel])
        side = np.unique(clabel[hc].astype(np.int64) * nfp + parent_face[hc])
        key = r[multi][ent] * nfp + ptopo.face[hp]
        inside = np.isin(key, side)
        n_in = np.bincount(ent, weights=inside, minlength=multi.size)
        use = inside | (n_in[ent] == 0)
        n_use = np.bincount(ent, weights=use, minlength=multi.size)
        rows.append(r[multi][ent[use]])
        cols.append(plabel[hp[use]])
        vals.append(w[multi][ent[use]] / n_use[ent[use]])
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(crv.size, prv.size))
    T.sum_duplicates()
    return T


def _extraordinary(topo: Topology, scheme: str) -> np.ndarray:
    regular = 6 if scheme == "loop" else 4
    val = topo.valence
    b = topo.vertex_is_boundary
    return topo.vertex_is_used & np.where(b, val != regular // 2 + 1, val != regular)


def _seed_blend(mesh: ControlMesh, scheme: str, variant: str, darts: str = "smooth") -> np.ndarray:
    """Control blend weights (module docstring): 1 at extraordinary vertices and their 1-rings;
    variant B: 0 at sharp vertices (darts too if ``darts == "sharp"``), which seed nothing."""
    topo, _, _, rule = _regions(mesh)
    ev = _extraordinary(topo, scheme)
    sharp_v = rule >= (1 if darts == "sharp" else 2)  # (DART,) CREASE or CORNER
    seeds = ev & ~sharp_v if variant == "b" else ev
    b = seeds.astype(np.float64)
    h = np.flatnonzero(seeds[topo.origin])
    b[topo.dest[h]] = 1.0
    b[topo.origin[topo.prev[h]]] = 1.0
    if variant == "b":
        b[sharp_v] = 0.0
    return b


def _reseed_decayed(grand: ControlMesh, parent: ControlMesh, child: ControlMesh, b: np.ndarray, scheme: str,
                    variant: str, darts: str) -> np.ndarray:
    """Variant B, ``b`` at ``child``: the vertices that turned from sharp (at ``grand``) to
    smooth (at ``parent``) and have had one smooth step since -- their semi-sharp edges or corner
    ran out, [ZBK] sec. 3.2, Fig. 4 -- seed 1 at themselves and their 1-rings in the child if
    they are extraordinary, as ``_seed_blend`` does; ``b`` elsewhere unchanged."""
    if variant != "b":
        return b  # variant A treated them as smooth vertices from the start
    gtopo, _, _, grule = _regions(grand)
    ptopo, _, _, prule = _regions(parent)
    ctopo = topology_of(child)
    thr = 1 if darts == "sharp" else 2
    loop = scheme == "loop"
    to_p = np.arange(gtopo.n_vertices) + (0 if loop else gtopo.n_faces + gtopo.n_edges)
    to_c = to_p + (0 if loop else ptopo.n_faces + ptopo.n_edges)
    turned = (grule >= thr) & (prule[to_p] < thr) & _extraordinary(ctopo, scheme)[to_c]
    if not turned.any():
        return b
    seeds = np.zeros(ctopo.n_vertices, bool)
    seeds[to_c[turned]] = True
    b = b.copy()
    b[seeds] = 1.0
    h = np.flatnonzero(seeds[ctopo.origin])
    b[ctopo.dest[h]] = 1.0
    b[ctopo.origin[ctopo.prev[h]]] = 1.0
    return b


@dataclass
class ShadingOperator:
    """Everything that depends on topology and tags only; ``evaluate(P)`` is a few products."""

    scheme: str
    levels: int
    normals_mode: str
    variant: str
    power: float
    mesh: ControlMesh  # the refined mesh (positions of the input it was built from)
    steps: list  # the L step operators: level-L points = S_L @ ... @ S_1 @ P
    first: sp.csr_matrix  # level-1 points from control points
    level1_edges: tuple  # (a, b) (H1,) level-1 vertices: corner c's cross product a[c] x b[c]
    normal_ops: list  # level-1 corner products -> level-1 regions -> ... -> level-L regions
    blend: np.ndarray  # (nv_L,) b
    limit: LimitMasks | None  # over the level-L points
    region_of_corner: np.ndarray  # (H_L,)
    region_vertex: np.ndarray  # (r_L,)
    keep_faces: np.ndarray  # (f_L,) bool: not a hole

    @property
    def geometry(self) -> sp.csr_matrix:
        """The composed operator (level-L points = geometry @ control points)."""
        g = sp.identity(self.steps[0].shape[1] if self.steps else self.mesh.n_vertices, format="csr")
        for S in self.steps:
            g = (S @ g).tocsr()
        return g

    def points(self, points: np.ndarray) -> np.ndarray:
        """Level-L points: the step operators applied in turn (cheaper than composing them)."""
        P = np.asarray(points, dtype=np.float64)
        for S in self.steps:
            P = S @ P
        return P

    def evaluate(self, points: np.ndarray) -> SubdividedMesh:
        P = np.asarray(points, dtype=np.float64)
        levels = []
        for S in self.steps:
            P = S @ P
            levels.append(P)
        out = P
        k = 3 if self.scheme == "loop" else 4
        every = bool(self.keep_faces.all())
        faces = self.mesh.face_vertices.reshape(-1, k)
        faces = faces if every else faces[self.keep_faces]
        if self.normals_mode == "none":
            return SubdividedMesh(out, faces, None, None)
        nl = self.limit.normals(out)
        if self.normals_mode == "limit":
            normals = nl
            blend = None
        else:
            p1 = levels[0]
            a, b = self.level1_edges
            ns = cross(p1[a], p1[b])
            for R in self.normal_ops:
                ns = R @ ns
            ns /= np.maximum(np.linalg.norm(ns, axis=1), 1e-300)[:, None]
            bp = self.blend[self.region_vertex] ** self.power
            normals = (1 - bp)[:, None] * nl + bp[:, None] * ns
            normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
            normals = np.where((bp == 0)[:, None], nl, normals)  # exactly N_L where b = 0
            blend = self.blend
        cn = self.region_of_corner.reshape(-1, k)
        cn = cn if every else cn[self.keep_faces]
        return SubdividedMesh(out, faces, cn, normals, blend)


def shading_operator(mesh: ControlMesh, levels: int, scheme: str = "loop", normals: str = "shading",
                     variant: str = "b", power: float = 1.0, rules: str = "opensubdiv",
                     crease_method: str | None = None, blend_level: int = 1, darts: str = "smooth") -> ShadingOperator:
    """Build the refined mesh's operators (module docstring).  levels >= 1 for normals;
    scheme "loop" or "catmark"; normals "none", "limit" or "shading"; variant "a" or "b";
    power p of [ZBK] eq. (1); rules and crease_method as ``patching.subdivision`` (catmark;
    crease_method None, the default: the mesh's ``crease_method``, for Loop too);
    blend_level: the level whose extraordinary vertices seed b (1, [ZBK] sec. 2.3's default;
    [ZBK] sec. 5 counts the vertices that need N_S with blending started at level 4); darts
    "smooth" (default) or "sharp" (module docstring)."""
    if scheme not in SCHEMES:
        raise UnsupportedError(f"--scheme must be one of {', '.join(SCHEMES)}, got '{scheme}'")
    if normals not in NORMAL_MODES:
        raise UnsupportedError(f"--normals must be one of {', '.join(NORMAL_MODES)}, got '{normals}'")
    if variant not in VARIANTS:
        raise UnsupportedError(f"--shading-variant must be a or b, got '{variant}'")
    if darts not in DART_MODES:
        raise UnsupportedError(f"darts must be treated as {' or '.join(DART_MODES)} vertices, got '{darts}'")
    if levels < 0 or (normals != "none" and levels < 1):
        raise UnsupportedError(f"normals need at least one subdivision step (-n {levels})")
    if normals != "none" and not 1 <= blend_level <= levels:
        raise UnsupportedError(f"the blend level must be between 1 and {levels}, got {blend_level}")
    if not power > 0:
        raise UnsupportedError(f"the blend power p must be > 0, got {power}")
    growth = 4 ** max(levels - 1, 0) * (4 if scheme == "loop" else 1)
    faces = (mesh.n_faces if scheme == "loop" else int(mesh.face_sizes.sum())) * growth if levels else mesh.n_faces
    if faces > MAX_SHADING_FACES:
        raise UnsupportedError(f"{levels} steps of {mesh.n_faces} faces make {faces:,} faces, more than {MAX_SHADING_FACES:,}", mesh.name)
    if scheme == "catmark" and normals != "none":
        from .limit import check_uniform_catmark

        check_uniform_catmark(mesh)
    nv0 = mesh.n_vertices
    first = sp.identity(nv0, format="csr")
    cur = mesh
    ops = []
    steps = []
    for level in range(levels):
        S, child, pface = _step(cur, scheme, rules, crease_method)
        steps.append(S)
        if level == 0:
            first = S
        ops.append((cur, S, child, pface))
        cur = child
    k = 3 if scheme == "loop" else 4
    holes = np.zeros(cur.n_faces, bool)
    if cur.holes:
        holes[np.fromiter(cur.holes, np.int64)] = True
    if scheme == "loop":
        from ..loop.refine import LoopLevel

        holes |= LoopLevel.of(cur, crease_method).holes  # interpolateboundary 0 at level 0
    keep = ~holes
    if cur.face_sizes.size and not np.all(cur.face_sizes == k) and levels > 0:
        raise AssertionError("refined faces of unexpected size")
    if normals == "none":
        return ShadingOperator(scheme, levels, normals, variant, power, cur, steps, first,
                               (np.zeros(0, np.int64), np.zeros(0, np.int64)), [], np.zeros(cur.n_vertices), None,
                               np.zeros(0, np.int64), np.zeros(0, np.int64), keep)
    L = limit_masks(cur, scheme, rules, crease_method)  # over the level-L points
    # level-1 regions (normals start there), blend weights seeded at blend_level
    m1 = ops[0][2]
    t1, label1, rv1, _ = _regions(m1)
    # level-1 region normals: the sum over the region's corners of their faces' Newell normals
    # (each face's sum of corner cross products), one sparse matrix over the corner products
    fv = m1.face_vertices
    nxt = t1.next
    H1 = fv.size
    per_face = sp.csr_matrix((np.ones(H1), (t1.face, np.arange(H1))), shape=(t1.n_faces, H1))
    to_region = sp.csr_matrix((np.ones(H1), (label1, t1.face)), shape=(rv1.size, t1.n_faces))
    ops_n = [(to_region @ per_face).tocsr()]
    plabel, prv, ptopo = label1, rv1, t1
    b = None
    for level, (cur_mesh, S, child, pface) in enumerate(ops[1:], start=1):
        if level == blend_level:
            b = _seed_blend(cur_mesh, scheme, variant, darts)
        ctopo, clabel, crv, _ = _regions(child)
        ops_n.append(region_operator(S, ptopo, plabel, prv, clabel, crv, pface))
        if b is not None:
            b = S @ b
            if level > blend_level:  # turned smooth after the seeding level
                b = _reseed_decayed(ops[level - 1][0], cur_mesh, child, b, scheme, variant, darts)
        plabel, prv, ptopo = clabel, crv, ctopo
    if b is None:
        b = _seed_blend(cur, scheme, variant, darts)
    return ShadingOperator(
        scheme, levels, normals, variant, power, cur, steps, first, (fv, fv[nxt]),
        ops_n, b, L, plabel if levels > 1 else label1, prv if levels > 1 else rv1, keep,
    )


def subdivide_with_normals(mesh: ControlMesh, levels: int, scheme: str = "loop", normals: str = "shading",
                           variant: str = "b", power: float = 1.0, rules: str = "opensubdiv",
                           crease_method: str | None = None) -> SubdividedMesh:
    """The refined mesh and its normals as arrays (``shading_operator(...).evaluate``)."""
    return shading_operator(mesh, levels, scheme, normals, variant, power, rules, crease_method).evaluate(mesh.vertices)
