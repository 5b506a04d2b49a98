"""One step of Catmull-Clark subdivision as a sparse operator, uniform or non-uniform, with sharp
and semi-sharp features (issue 7; seeds 000, 001, 002 Appendix).

``subdivision_operator(mesh)`` returns ``S`` (scipy.sparse CSR, new points = ``S @ old``) and the
refined ControlMesh (positions already ``S @ mesh.vertices``).  ``S`` depends on topology,
knot intervals and tags only.  The masks live in ``subdivision_rules`` (curves, BLZ gamma) and
``eigen_polyhedron`` (a non-uniform extraordinary point's 1-ring); this module gathers
intervals and tags from the topology and assembles the rows with numpy, looping in Python only
over extraordinary points (each solved once per configuration by ``eigen_polyhedron``'s cache).

Child numbering (as OpenSubdiv's refiner: face points, then edge points, then vertex points)::

    face point of face f       f
    edge point of edge e       n_faces + e
    vertex point of vertex v   n_faces + n_edges + v

Child faces: parent half-edge ``h`` (corner ``origin[h]`` of face ``face[h]``) becomes child
face ``h`` = ``(V(origin h), E(edge h), F(face h), E(edge prev h))``, same orientation::

        v_{i+1}
          |  \\
     E(h_i)---F        child face of corner i:  V(v_i) -> E(h_i) -> F -> E(h_{i-1})
          |   |
         v_i--E(h_{i-1})--v_{i-1}

Two rule sets (``rules``):

* ``"opensubdiv"``: OpenSubdiv's Catmark rules (``sdc/catmarkScheme.h``, ``sdc/crease.cpp``,
  ``sdc/scheme.h``, ``far/topologyRefinerFactory.cpp``): boundary edges infinitely sharp in every
  interpolateboundary mode, a vertex with one face and two edges an infinitely sharp corner in
  mode 1 (edge-and-corner); vertex rule from (vertex sharpness, number of sharp edges): corner
  if the vertex is sharp or has > 2 sharp edges, crease with 2, dart with 1, smooth with 0;
  smooth = Catmull-Clark, dart = smooth, crease = ``3/4 V + 1/8 (ends)``, corner = ``V``; edge
  points: smooth ``(a + b + F_0 + F_1) / 4``, sharp ``(a + b) / 2``, and ``s (sharp) +
  (1 - s)(smooth)`` for ``0 < s < 1``; semi-sharp vertices blend the parent and child rules
  with ``Crease::ComputeFractionalWeightAtVertex``.  Sharpness decrements by 1 a step
  (OpenSubdiv's uniform creasing) or, with ``crease_method="chaikin"``, by its Chaikin rule
  (``_chaikin``: each half of an edge from the semi-sharp edges at its end; the edge and
  vertex blends then read the halves, as ``Far::PrimvarRefiner`` does).  Uniform intervals
  only: a non-uniform mesh is refused with a KnotError.
* ``"seed"`` (default): seed 000.  Uniform intervals: the Biermann-Levin-Zorin rules of its
  section 2 (the same vertex classification; an untagged edge next to a tagged vertex gets
  ``gamma = 3/8 - cos(theta)/4``, theta ``2 pi/m`` at a dart, ``pi/m`` at a crease, ``alpha/m``
  at a convex corner); semi-sharp sharpness handled exactly as under ``"opensubdiv"`` (seed 000
  section 5 clears the tags after ``s`` steps; the fractional blend is OpenSubdiv's).
  Non-uniform intervals: midpoint knot insertion in regular regions (tensor products of the
  curve rules, ``subdivision_rules``), non-uniform cubic B-spline crease curves, and the
  eigen-polyhedron rules of [LFS16] (``eigen_polyhedron``, angles of seed 001 with
  ``angles="modified"``) on faces and edges around an untagged extraordinary point.

Choices where the seeds are silent, written once:

* Corner sector angle ``alpha`` (BLZ: "the angle of the sector"): the sum of the corner angles
  ``pi (k - 2) / k`` of the sector's k-gons, a topological angle, so that ``S`` does not depend
  on positions; a quad sector of m faces gets ``theta = pi/2``, the standard rule (a cube's
  corner angles are exactly that).  Convex and concave sectors (seed 000 section 2: "convex
  unless tagged") need no tag here: BLZ's concave rule ``theta = (2 pi - alpha)/m`` takes
  alpha as the convex angle between the sector's two crease edges, which for a quad sector
  spanning m pi/2 (m >= 3, e.g. the three faces of an L's inner corner) is 2 pi - m pi/2, and
  gives theta = pi/2 again: with topological angles the two rules coincide.  Only geometric
  angles would tell them apart, and those would make S depend on positions.
* An untagged edge with *both* ends tagged: the mean of the two BLZ rules.
* An endpoint's "interval beyond" (``d_{i-1}`` of the curve rules): through a regular smooth
  vertex (interior, valence 4, quads) the straight continuation's interval; along a crease
  through a crease vertex the other crease edge's, also for the face and edge points beside a
  regular boundary vertex (two quads, valence 3), so that they read the boundary curve's knots;
  elsewhere (corner, dart, a spoke into the boundary, EP) the edge's own interval, the mirror
  image that seed 000 Fig. 8 assumes (``d-bar = d``).  With it a crease ending at a corner
  interpolates the corner and its first edge point is the midpoint, as seed 000's corner eigen-polyhedron (``P^1 = P^0 / 2``) requires.
* Zero intervals (multiple knots, DESIGN 2) split into two zero halves.  On a clamped side (an
  open grid whose outer strips carry 0) every point of the zero strips then lies on the
  boundary curve (zero-width faces stay degenerate) and the rest is the clamped NURBS after
  midpoint knot insertion, step after step (tests: three steps against OpenCASCADE).
* Rows claimed by two local solves (a face or edge touching two EPs or tagged vertices, as
  every face along a crease does): their mean.  With equal claims (uniform intervals) the
  mean is the rule itself.
* A non-uniform smooth vertex of valence != 4 that no EP solve covers (a semi-sharp vertex
  whose tags fade this step): [LFS16]'s vertex rule (``eigen_polyhedron.vertex_rule_weights``).
* Non-quad faces (first step only): centroid face point, Catmull-Clark rows for their edges and
  vertices; the new edges inside the face get half the interval of the parallel parent edges,
  which is consistent (strips) only if ``d(h_{i-1}) = d(h_{i+1})`` around the face (all equal
  for odd faces, alternating for even ones): otherwise UnsupportedError.
* Non-uniform intervals at tagged vertices (seed 000 section 4): the generalised
  eigen-polyhedron rules (``subdivision_rules.tagged_rules_batch``) give the face points
  around the vertex, the edge points of its untagged spokes and a dart's vertex point; crease
  edges and crease/corner vertices follow the non-uniform crease curve.  Where a tagged
  vertex's spoke intervals are all equal, section 2's BLZ rule is kept instead (on top of knot
  insertion): section 4's edge form with equal intervals is not BLZ's rule when
  theta != pi/2 (tests record the difference), and the acceptance asks for section 2 there.
  A crease sector of a single face (theta = pi) makes the polyhedron degenerate: knot
  insertion with BLZ there too.  A zero spoke interval (a multiple knot, DESIGN 2): knot
  insertion on an open boundary (a clamped side, exactly the clamped NURBS); inside the mesh
  refused (``_refuse_tagged_on_zero``: the rules' eps -> 0 limit exists, but it opens the
  zero strip and the patches beside it do not close up).
* An interior vertex of valence 2 with non-uniform intervals (two quads sharing two edges).
  The eigen-polyhedron of seed 000 section 3 needs n >= 3 (at n = 2, ``c_n = -1`` and
  ``tau = 4 / (c_n + 1 + sqrt((c_n + 9)(c_n + 1)))`` is infinite: the two spokes are opposite
  and the face points collapse onto V), so no face or edge rule comes from a solve there.
  What the seeds do define: the vertex rule of [LFS16] (seed 002 eq. 11, seed 000 eqs. 6-7)
  is an explicit formula valid for any n, and the faces and spokes around the vertex take
  the midpoint knot-insertion rules of regular regions (curve rules, with the spoke's own
  interval beyond the vertex, as at every non-regular vertex).  At n = 2 the vertex rule's
  ``g_i = 1/2`` and ``f_i = d_0 d_1`` for both spokes, so it is Catmull-Clark's
  ``V/8 + 3/8 (E_0 + E_1) + (F_0 + F_1)/16`` whatever the intervals; and once the spokes are
  split (both halves of a spoke carry one interval) the knot-insertion face and edge rows of
  the 1-ring are Catmull-Clark's too.  So the 1-ring's stationary matrix is exactly
  Catmull-Clark's at valence 2 (eigenvalues 1, 1/4, 1/4, 1/8, -1/4: Catmull-Clark's own
  valence-2 structure, whose -1/4 matches the subdominant pair in modulus), its limit point
  is Catmull-Clark's mask ``(2 V + 2 (E_0 + E_1) + (F_0 + F_1)/2) / 7``, and the intervals act
  through the first step and the neighbours' rows.  Rows stay non-negative, so the limit
  stays in the control points' convex hull (tests).  A crease through the vertex takes the
  crease curve's rules; a dart or corner there takes knot insertion with BLZ's edge
  correction, the fallback already used where the generalised eigen-polyhedron is undefined
  (a crease sector of one face, a zero spoke interval).  Limit tangents at an interior
  valence-2 vertex are NaN (the -1/4 eigenvalue: no single tangent plane in general).
* Not implemented (UnsupportedError, never a wrong surface): a rule whose bilinear solve has
  no root in the unit square (extreme interval ratios).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .blas import one_blas_thread
from .errors import KnotError, UnsupportedError
from .mesh import INFINITELY_SHARP, ControlMesh
from .subdivision_rules import (
    CORNER,
    KINDS,
    CREASE,
    DART,
    SMOOTH,
    blz_gamma,
    curve_derivative_weights,
    curve_edge_weights,
    curve_limit_weights,
    curve_vertex_weights,
    tagged_rules_batch,
)
from .topology import Topology

__all__ = [
    "subdivide",
    "subdivision_operator",
    "limit_operator",
    "limit_points",
    "limit_tangents",
    "rules_tag",
    "RULE_SETS",
    "ANGLE_CHOICES",
    "CREASE_METHODS",
]

RULE_SETS = ("seed", "opensubdiv")
ANGLE_CHOICES = ("standard", "modified")
#: How semi-sharp sharpness decays a step (OpenSubdiv's Sdc::Options::CreasingMethod).
CREASE_METHODS = ("uniform", "chaikin")
#: Name of the OBJ tag that records the rule set: ``t nupatch_rules 0/0/1 seed``.
RULES_TAG = "nupatch_rules"


def rules_tag(rules: str) -> str:
    """The OBJ tag line recording the rule set of a subdivided mesh."""
    return f"t {RULES_TAG} 0/0/1 {rules}"


def _decrement(s: np.ndarray) -> np.ndarray:
    """OpenSubdiv's uniform creasing: ``s - 1`` (0 when ``s <= 1``), infinite stays infinite."""
    return np.where(np.isinf(s), np.inf, np.where(s > 1.0, s - 1.0, 0.0))


def _chaikin(es: np.ndarray, edges: np.ndarray, nv: int) -> np.ndarray:
    """OpenSubdiv's Chaikin creasing (``Sdc::Crease::SubdivideEdgeSharpnessesAroundVertex``
    with ``CREASE_CHAIKIN``): (e, 2) sharpness of the half of every edge at its end
    ``edges[:, k]``.

    At a vertex with c >= 2 semi-sharp edges (0 < s < infinity) a semi-sharp edge's half gets
    ``3/4 s + 1/4 (mean of the other c - 1 semi-sharp sharpnesses) - 1`` (0 if that is <= 0);
    with c = 1 the uniform ``s - 1``; smooth halves stay 0, infinite ones infinite.  The two
    halves of an edge may differ (each reads its own end's neighbourhood).  A half is never
    sharper than the largest sharpness at its end minus one, so ``ceil(max s)`` steps still
    clear every semi-sharp tag."""
    semi = (es > 0) & np.isfinite(es)
    total = np.zeros(nv)
    count = np.zeros(nv)
    for k in (0, 1):
        np.add.at(total, edges[semi, k], es[semi])
        np.add.at(count, edges[semi, k], 1.0)
    out = np.empty((es.size, 2))
    finite = np.where(semi, es, 0.0)
    for k in (0, 1):
        c, t = count[edges[:, k]], total[edges[:, k]]
        others = (t - finite) / np.maximum(c - 1.0, 1.0)
        ch = 0.75 * finite + 0.25 * others - 1.0
        out[:, k] = np.where(semi & (c > 1), np.where(ch > 0, ch, 0.0), _decrement(es))
    return out


class _Rows:
    """COO triplets of S, gathered rule by rule."""

    def __init__(self) -> None:
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []

    def add(self, rows, cols, vals) -> None:
        rows, cols, vals = np.broadcast_arrays(
            np.asarray(rows, np.int64), np.asarray(cols, np.int64), np.asarray(vals, np.float64)
        )
        self.r.append(rows.ravel())
        self.c.append(cols.ravel())
        self.v.append(vals.ravel())

    def matrix(self, shape) -> sp.csr_matrix:
        r = np.concatenate(self.r) if self.r else np.zeros(0, np.int64)
        c = np.concatenate(self.c) if self.c else np.zeros(0, np.int64)
        v = np.concatenate(self.v) if self.v else np.zeros(0)
        m = sp.csr_matrix((v, (r, c)), shape=shape)
        m.sum_duplicates()
        m.eliminate_zeros()
        return m


@dataclass
class _Level:
    """Tags of one sharpness level (the parent's, or the child's after decrementing)."""

    sharp: np.ndarray  # (e,) bool
    vertex_sharp: np.ndarray  # (v,) bool
    rule: np.ndarray  # (v,) int8: SMOOTH, DART, CREASE, CORNER
    crease_edges: np.ndarray  # (v, 2) int64: the two sharp edges of a CREASE vertex, else -1


class _Context:
    """Topology tables, intervals and tags of one mesh, as flat arrays (read-only)."""

    def __init__(self, mesh: ControlMesh, crease_method: str = "uniform") -> None:
        t = Topology(mesh)
        self.mesh, self.topo = mesh, t
        self.crease_method = crease_method
        self.H = t.origin.size
        self.nf, self.ne, self.nv = t.n_faces, t.n_edges, t.n_vertices
        self.origin, self.dest, self.nxt, self.prv = t.origin, t.dest, t.next, t.prev
        self.twin, self.face, self.eoh, self.edges = t.twin, t.face, t.edge_of, t.edges
        self.fsize = np.diff(mesh.face_offsets)
        self.ksize = self.fsize[self.face]  # (H,) size of the face of each half-edge
        self.d_e = t.edge_interval
        self.d_h = t.halfedge_interval
        si = t.strip_interval
        self.uniform = bool(si.size == 0 or np.all(si == si[0]))
        self.valence = t.valence
        self.n_faces_at = np.bincount(self.origin, minlength=self.nv)
        self.v_boundary = t.vertex_is_boundary
        self.e_boundary = t.edge_is_boundary
        # Sharpness: infinite at >= 10 and on every boundary edge (OpenSubdiv, all modes).
        es = t.edge_sharpness.copy()
        es[es >= INFINITELY_SHARP] = np.inf
        es[self.e_boundary] = np.inf
        self.es = es
        vs = np.zeros(self.nv)
        if mesh.corners:
            idx = np.fromiter(mesh.corners.keys(), np.int64)
            vs[idx] = np.fromiter(mesh.corners.values(), np.float64)
        vs[vs >= INFINITELY_SHARP] = np.inf
        if mesh.interpolate_boundary == 1:
            topological_corner = self.v_boundary & (self.n_faces_at == 1) & (self.valence == 2)
            vs[topological_corner] = np.inf
        self.vs = vs
        # Vertex touches a non-quad face.
        self.v_nonquad = np.zeros(self.nv, bool)
        self.v_nonquad[self.origin[self.ksize != 4]] = True

    # -- levels -------------------------------------------------------------------------------
    def level(self, es: np.ndarray, vs: np.ndarray) -> _Level:
        """Rules from edge sharpness ``es``, (e,) or (e, 2) per end ``edges[:, k]`` (the
        child's halves, which Chaikin creasing may give two values), and vertex sharpness."""
        es = np.stack([es, es], axis=1) if es.ndim == 1 else es
        at_end = es > 0
        sharp = at_end.any(axis=1)
        count = np.bincount(self.edges[at_end], minlength=self.nv)
        vsharp = vs > 0
        rule = np.where(vsharp | (count > 2), CORNER, np.minimum(count, 2)).astype(np.int8)
        ends = np.full((self.nv, 2), -1, np.int64)
        s0, s1 = np.flatnonzero(at_end[:, 0]), np.flatnonzero(at_end[:, 1])
        if s0.size + s1.size:
            vv = np.concatenate([self.edges[s0, 0], self.edges[s1, 1]])
            ee = np.concatenate([s0, s1])
            order = np.argsort(vv, kind="stable")
            vv, ee = vv[order], ee[order]
            first = np.searchsorted(vv, np.arange(self.nv))
            crease = np.flatnonzero(rule == CREASE)
            ends[crease, 0] = ee[first[crease]]
            ends[crease, 1] = ee[first[crease] + 1]
        return _Level(sharp, vsharp, rule, ends)

    @cached_property
    def parent(self) -> _Level:
        return self.level(self.es, self.vs)

    @cached_property
    def child_es(self) -> np.ndarray:
        """(e, 2) sharpness of the child half of every edge at its end ``edges[:, k]``."""
        if self.crease_method == "chaikin":
            return _chaikin(self.es, self.edges, self.nv)
        d = _decrement(self.es)
        return np.stack([d, d], axis=1)

    @cached_property
    def child(self) -> _Level:
        return self.level(self.child_es, _decrement(self.vs))

    @cached_property
    def edge_sharp_weight(self) -> np.ndarray:
        """(e,) weight of the crease rule in the edge point, the rest going to the smooth rule
        (``Sdc::Scheme::ComputeEdgeVertexMask`` as ``Far::PrimvarRefiner`` calls it): 0 on a
        smooth edge; 1 when both child halves stay sharp (the child vertex is a crease);
        otherwise the parent sharpness s.  Uniform creasing: ``min(s, 1)``.  Chaikin creasing
        can keep an edge of s < 1 sharp (1) and can clear a half of an edge of s > 1: then
        OpenSubdiv's weight is s itself, unclamped (the smooth rule gets 1 - s < 0), kept so
        that the points equal OpenSubdiv's."""
        both = (self.child_es > 0).all(axis=1)
        return np.where(self.es > 0, np.where(both, 1.0, self.es), 0.0)

    # -- half-edge helpers --------------------------------------------------------------------
    @cached_property
    def face_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(h, h') for every half-edge h and every half-edge h' of the same face."""
        k = self.ksize
        h = np.repeat(np.arange(self.H), k)
        start = np.repeat(np.cumsum(k) - k, k)
        local = np.arange(h.size) - start
        base = self.mesh.face_offsets[self.face[h]]
        return h, base + local

    @cached_property
    def regular_line_vertex(self) -> np.ndarray:
        """(v,) bool: straight lines continue through v (interior, valence 4, quads, untagged)."""
        return (
            ~self.v_boundary
            & (self.valence == 4)
            & ~self.v_nonquad
            & (self.parent.rule == SMOOTH)
            & (self.n_faces_at == 4)
        )

    @cached_property
    def regular_boundary_vertex(self) -> np.ndarray:
        """(v,) bool: the boundary line continues straight through v (two quads, valence 3,
        no tag but the boundary crease itself)."""
        return (
            self.v_boundary
            & (self.valence == 3)
            & ~self.v_nonquad
            & (self.parent.rule == CREASE)
            & (self.n_faces_at == 2)
        )

    @cached_property
    def ahead(self) -> np.ndarray:
        """(H,) interval beyond dest(h) on h's straight line; h's own where there is no line.

        Lines run straight through regular interior vertices, and along the boundary through
        regular boundary vertices: there the boundary curve's next interval, as the boundary
        crease rule (``crease_beyond``) reads it, so that the edge points of the spokes into the
        boundary see the same knots as the boundary curve (a clamped side, DESIGN 2, then
        keeps its zero strips degenerate: every point of a zero strip lies on the boundary)."""
        out = self.d_h.copy()
        b = self.dest
        ok = self.regular_line_vertex[b]
        hs = np.flatnonzero(ok)
        c = self.nxt[self.twin[self.nxt[hs]]]
        out[hs] = self.d_h[c]
        # along the boundary: h's edge is a boundary edge, next(h) the spoke into the interior
        hb = np.flatnonzero(self.regular_boundary_vertex[b] & (self.twin < 0) & (self.twin[self.nxt] >= 0))
        out[hb] = self.d_h[self.nxt[self.twin[self.nxt[hb]]]]
        return out

    def ahead_back(self, h: np.ndarray) -> np.ndarray:
        """Interval beyond origin(h), backwards along h (through the twin; along the boundary
        through a regular boundary vertex; else h's own interval)."""
        t = self.twin[h]
        back = self.twin[self.prv[h]]  # spoke leaving origin(h) in the neighbouring face
        along = (t < 0) & self.regular_boundary_vertex[self.origin[h]] & (back >= 0)
        other = self.d_h[self.prv[np.maximum(back, 0)]]
        return np.where(t >= 0, self.ahead[np.maximum(t, 0)], np.where(along, other, self.d_h[h]))

    def crease_beyond(self, lev: _Level, e: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Interval beyond vertex v along the crease curve through sharp edge e."""
        e0, e1 = lev.crease_edges[v, 0], lev.crease_edges[v, 1]
        other = np.where(e0 == e, e1, e0)
        through = lev.rule[v] == CREASE
        return np.where(through, self.d_e[np.maximum(other, 0)], self.d_e[e])

    # -- sectors (seed rules) -----------------------------------------------------------------
    def theta_at(self, lev: _Level, h: np.ndarray) -> np.ndarray:
        """BLZ's theta at origin(h) for the untagged edge of h (NaN where origin is untagged)."""
        into = self.twin[self.prv]  # corner h is linked to the corner across edge prev(h)
        link = (into >= 0) & ~lev.sharp[self.eoh[self.prv]]
        src = np.flatnonzero(link)
        g = sp.coo_matrix((np.ones(src.size), (src, into[src])), shape=(self.H, self.H))
        _, label = connected_components(g, directed=False)
        m = np.bincount(label)
        alpha = np.bincount(label, weights=math.pi * (self.ksize - 2) / self.ksize)
        lab = label[h]
        rule = lev.rule[self.origin[h]]
        theta = np.full(h.size, np.nan)
        theta = np.where(rule == DART, 2 * math.pi / m[lab], theta)
        theta = np.where(rule == CREASE, math.pi / m[lab], theta)
        theta = np.where(rule == CORNER, alpha[lab] / m[lab], theta)
        return theta


# ------------------------------------------------------------------------------------------
# Rows


def _face_rows(ctx: _Context, rows: _Rows, faces_mask: np.ndarray) -> None:
    """Face points: centroid (uniform, non-quads) or the tensor product of the curve edge rules
    (non-uniform quads: the bilinear form of seed 000 eq. 18 with knot-insertion weights)."""
    h = np.flatnonzero(faces_mask[ctx.face])
    if ctx.uniform:
        rows.add(ctx.face[h], ctx.origin[h], 1.0 / ctx.ksize[h])
        return
    nonquad = ctx.ksize[h] != 4
    hn = h[nonquad]
    rows.add(ctx.face[hn], ctx.origin[hn], 1.0 / ctx.ksize[hn])
    f = np.unique(ctx.face[h[~nonquad]])
    h0 = ctx.mesh.face_offsets[f]
    h1, h2, h3 = h0 + 1, h0 + 2, h0 + 3
    # u: along h0 (v0 -> v1) and h2 (v2 -> v3); v: along h1 (v1 -> v2) and h3 (v3 -> v0).
    du = ctx.d_h[h0]
    du_left = 0.5 * (ctx.ahead_back(h0) + ctx.ahead[h2])
    du_right = 0.5 * (ctx.ahead[h0] + ctx.ahead_back(h2))
    dv = ctx.d_h[h1]
    dv_bottom = 0.5 * (ctx.ahead_back(h1) + ctx.ahead[h3])
    dv_top = 0.5 * (ctx.ahead[h1] + ctx.ahead_back(h3))
    a_left, a_right = curve_edge_weights(du_left, du, du_right)
    b_bottom, b_top = curve_edge_weights(dv_bottom, dv, dv_top)
    o = ctx.origin
    rows.add(f, o[h0], a_left * b_bottom)
    rows.add(f, o[h1], a_right * b_bottom)
    rows.add(f, o[h2], a_right * b_top)
    rows.add(f, o[h3], a_left * b_top)


def _cc_edge_rows(ctx: _Context, rows: _Rows, e: np.ndarray, scale: np.ndarray) -> None:
    """Catmull-Clark's smooth edge point (a + b + F_0 + F_1) / 4 (face points as centroids)."""
    if e.size == 0:
        return
    sc = np.zeros(ctx.ne)
    sc[e] = scale
    row_e = ctx.nf + e
    rows.add(row_e, ctx.edges[e, 0], 0.25 * scale)
    rows.add(row_e, ctx.edges[e, 1], 0.25 * scale)
    ph, php = ctx.face_pairs
    sel = np.flatnonzero(sc[ctx.eoh[ph]] != 0)
    ph, php = ph[sel], php[sel]
    rows.add(ctx.nf + ctx.eoh[ph], ctx.origin[php], sc[ctx.eoh[ph]] * 0.25 / ctx.ksize[ph])


def _tensor_edge_rows(ctx: _Context, rows: _Rows, e: np.ndarray, scale: np.ndarray) -> None:
    """Non-uniform smooth edge point between two quads: the curve edge rule along the edge times
    the curve vertex rule across it (midpoint knot insertion)."""
    if e.size == 0:
        return
    h = ctx.topo.edge_halfedge[e]
    t = ctx.twin[h]
    a, b = ctx.origin[h], ctx.dest[h]
    wa, wb = curve_edge_weights(ctx.ahead[t], ctx.d_h[h], ctx.ahead[h])
    nh, nt = ctx.nxt[h], ctx.nxt[t]
    w_f, w_mid, w_g = curve_vertex_weights(ctx.ahead[nh], ctx.d_h[nh], ctx.d_h[nt], ctx.ahead[nt])
    c, x = ctx.dest[nh], ctx.dest[ctx.nxt[nh]]  # face of h: a, b, c, x
    y, z = ctx.dest[nt], ctx.dest[ctx.nxt[nt]]  # face of t: b, a, y, z
    row = ctx.nf + e
    rows.add(row, a, scale * wa * w_mid)
    rows.add(row, b, scale * wb * w_mid)
    rows.add(row, c, scale * wb * w_f)
    rows.add(row, x, scale * wa * w_f)
    rows.add(row, y, scale * wa * w_g)
    rows.add(row, z, scale * wb * w_g)


def _blz_edge_correction(ctx: _Context, rows: _Rows, lev: _Level, e: np.ndarray, scale) -> None:
    """BLZ's modification next to tagged vertices, as a correction of the standard rule:
    ``(3/8 - gamma)(tagged end - other end)`` (mean of the two when both ends are tagged)."""
    if e.size == 0:
        return
    h = ctx.topo.edge_halfedge[e]
    t = ctx.twin[h]
    a, b = ctx.origin[h], ctx.dest[h]
    tag_a, tag_b = lev.rule[a] != SMOOTH, lev.rule[b] != SMOOTH
    both = np.where(tag_a & tag_b, 0.5, 1.0)
    delta_a = np.where(tag_a, 0.375 - blz_gamma(ctx.theta_at(lev, h)), 0.0)
    delta_b = np.where(tag_b, 0.375 - blz_gamma(ctx.theta_at(lev, t)), 0.0)
    corr = scale * both * (delta_a - delta_b)
    row = ctx.nf + e
    rows.add(row, a, corr)
    rows.add(row, b, -corr)


def _sharp_edge_rows(ctx: _Context, rows: _Rows, e: np.ndarray, scale: np.ndarray, seed: bool) -> None:
    """Crease edge point: midpoint (uniform), or the curve edge rule along the crease curve."""
    if e.size == 0:
        return
    a, b = ctx.edges[e, 0], ctx.edges[e, 1]
    row = ctx.nf + e
    if ctx.uniform or not seed:
        rows.add(row, a, 0.5 * scale)
        rows.add(row, b, 0.5 * scale)
        return
    lev = ctx.parent
    wa, wb = curve_edge_weights(ctx.crease_beyond(lev, e, a), ctx.d_e[e], ctx.crease_beyond(lev, e, b))
    rows.add(row, a, wa * scale)
    rows.add(row, b, wb * scale)


def _cc_vertex_rows(ctx: _Context, rows: _Rows, v: np.ndarray, scale: np.ndarray) -> None:
    """Catmull-Clark smooth vertex: (n-2)/n V + (sum of edge neighbours + sum of face points)/n^2."""
    if v.size == 0:
        return
    n = ctx.valence[v].astype(np.float64)
    row = ctx.nf + ctx.ne + v
    rows.add(row, v, scale * (n - 2.0) / n)
    sc = np.zeros(ctx.nv)
    sc[v] = scale
    hs = np.flatnonzero(sc[ctx.origin] != 0)
    o = ctx.origin[hs]
    nn = ctx.valence[o].astype(np.float64)
    rows.add(ctx.nf + ctx.ne + o, ctx.dest[hs], sc[o] / nn**2)
    ph, php = ctx.face_pairs
    sel = np.flatnonzero(sc[ctx.origin[ph]] != 0)
    ph, php = ph[sel], php[sel]
    o = ctx.origin[ph]
    nn = ctx.valence[o].astype(np.float64)
    rows.add(ctx.nf + ctx.ne + o, ctx.origin[php], sc[o] / (nn**2 * ctx.ksize[ph]))


def _tensor_vertex_rows(ctx: _Context, rows: _Rows, v: np.ndarray, scale: np.ndarray) -> None:
    """Non-uniform regular vertex (valence 4, quads): product of the curve vertex rules along the
    two lines of spokes 0-2 and 1-3."""
    if v.size == 0:
        return
    t = ctx.topo
    s0 = t.outgoing[v]
    s1 = t.rotate(s0)
    s2 = t.rotate(s1)
    s3 = t.rotate(s2)
    d = [ctx.d_h[s] for s in (s0, s1, s2, s3)]
    a = [ctx.ahead[s] for s in (s0, s1, s2, s3)]
    mA, cA, pA = curve_vertex_weights(a[2], d[2], d[0], a[0])  # E_2 - V - E_0
    mB, cB, pB = curve_vertex_weights(a[3], d[3], d[1], a[1])  # E_3 - V - E_1
    E = [ctx.dest[s] for s in (s0, s1, s2, s3)]
    F = [ctx.dest[ctx.nxt[s]] for s in (s0, s1, s2, s3)]  # F_i between spokes i and i+1
    row = ctx.nf + ctx.ne + v
    rows.add(row, v, scale * cA * cB)
    rows.add(row, E[0], scale * pA * cB)
    rows.add(row, E[2], scale * mA * cB)
    rows.add(row, E[1], scale * cA * pB)
    rows.add(row, E[3], scale * cA * mB)
    rows.add(row, F[0], scale * pA * pB)
    rows.add(row, F[1], scale * mA * pB)
    rows.add(row, F[2], scale * mA * mB)
    rows.add(row, F[3], scale * pA * mB)


def _crease_vertex_rows(ctx: _Context, rows: _Rows, lev: _Level, v: np.ndarray, scale, seed: bool) -> None:
    """Crease vertex: 3/4 V + 1/8 (ends) uniform; the curve vertex rule along the crease curve
    (seed 000 eq. 11) for non-uniform intervals."""
    if v.size == 0:
        return
    e0, e1 = lev.crease_edges[v, 0], lev.crease_edges[v, 1]
    end0 = np.where(ctx.edges[e0, 0] == v, ctx.edges[e0, 1], ctx.edges[e0, 0])
    end1 = np.where(ctx.edges[e1, 0] == v, ctx.edges[e1, 1], ctx.edges[e1, 0])
    row = ctx.nf + ctx.ne + v
    if ctx.uniform or not seed:
        w0, wc, w1 = 0.125, 0.75, 0.125
    else:
        w0, wc, w1 = curve_vertex_weights(
            ctx.crease_beyond(lev, e0, end0), ctx.d_e[e0], ctx.d_e[e1], ctx.crease_beyond(lev, e1, end1)
        )
    rows.add(row, end0, scale * w0)
    rows.add(row, v, scale * wc)
    rows.add(row, end1, scale * w1)


# ------------------------------------------------------------------------------------------
# Extraordinary points (non-uniform): eigen-polyhedron rules


class _Claims:
    """Rows of S claimed by local solves (EPs, tagged vertices), as blocks of a local matrix:
    a row claimed by k solves gets the mean of the k claims."""

    def __init__(self, n_out: int) -> None:
        self.n_out = n_out
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self, rows: np.ndarray, cols: np.ndarray, weights: np.ndarray) -> None:
        """rows (k,) row ids of S, cols (k, c) column ids, weights (k, c)."""
        self.blocks.append((rows, cols, weights))

    @cached_property
    def count(self) -> np.ndarray:
        """(n_out,) number of claims of every row of S."""
        rows = [b[0] for b in self.blocks]
        return np.bincount(np.concatenate(rows), minlength=self.n_out) if rows else np.zeros(self.n_out, np.int64)

    def emit(self, out: _Rows) -> None:
        for rows, cols, weights in self.blocks:
            out.add(rows[:, None], cols, weights / self.count[rows][:, None])


def _ep_rows(ctx: _Context, eps: np.ndarray, angles: str, claims: _Claims) -> None:
    """Rows of the [LFS16] local matrix around every untagged EP, the EPs of one valence in one
    vectorised solve (``eigen_polyhedron.local_subdivision_matrices``)."""
    from . import eigen_polyhedron as eig

    for n in np.unique(ctx.valence[eps]).tolist():
        v = eps[ctx.valence[eps] == n]
        ring = np.stack([ctx.topo.one_ring(x) for x in v.tolist()])  # (g, n) spokes
        d = ctx.d_h[ring]
        try:
            m = eig.local_subdivision_matrices(d, angles=angles)
        except ValueError as exc:
            k = exc.index[0] if isinstance(exc, eig.BilinearError) else 0
            raise UnsupportedError(
                f"eigen-polyhedron rule undefined at extraordinary vertex {v[k]} (valence {n}, "
                f"spoke intervals {d[k].tolist()}): {exc}",
                ctx.mesh.where("vertex", int(v[k])),
            ) from None
        cols = np.concatenate([v[:, None], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]], axis=1)
        targets = np.concatenate([ctx.nf + ctx.ne + v[:, None], ctx.nf + ctx.eoh[ring], ctx.face[ring]], axis=1)
        claims.add(targets.ravel(), np.repeat(cols, 2 * n + 1, axis=0), m.reshape(-1, 2 * n + 1))


def _tagged_rows(ctx: _Context, claims: _Claims) -> None:
    """Seed 000 section 4 at tagged vertices (non-uniform): the generalised eigen-polyhedron
    rules of ``subdivision_rules.tagged_rules_batch`` claim the face points around the vertex,
    the edge points of its untagged spokes and (dart) its vertex point; vertices of one kind
    and shape are solved together.  Not used, so that the BLZ rules of section 2 apply there
    (on top of knot insertion): a vertex whose spoke intervals are all equal (section 4 with
    equal intervals is not section 2 for theta != pi/2, see the report in
    ``tagged_vertex_rules``' tests; a dart of valence != 4 still takes its vertex row, which is
    Catmull-Clark's then), a crease sector of one face (theta = pi, a degenerate polyhedron),
    and vertices next to a non-quad face."""
    from .eigen_polyhedron import BilinearError

    lev = ctx.parent
    interior2 = ~ctx.v_boundary & (ctx.valence == 2)  # no polyhedron: knot insertion with BLZ
    cand = np.flatnonzero((lev.rule != SMOOTH) & ~ctx.v_nonquad & ctx.topo.vertex_is_used & ~interior2)
    groups: dict[tuple, list] = {}
    for v in cand.tolist():
        kind = int(lev.rule[v])
        ring = ctx.topo.one_ring(v)
        boundary = bool(ctx.v_boundary[v])
        f = ring.size
        spoke_edges = ctx.eoh[ring]
        ends = ctx.dest[ring]
        if boundary:
            last = ctx.prv[ring[-1]]
            spoke_edges = np.append(spoke_edges, ctx.eoh[last])
            ends = np.append(ends, ctx.origin[last])
        n = spoke_edges.size
        sharp = np.flatnonzero(lev.sharp[spoke_edges])
        if not boundary and sharp.size:  # rotate: a sharp spoke first
            k = int(sharp[0])
            ring, spoke_edges, ends = np.roll(ring, -k), np.roll(spoke_edges, -k), np.roll(ends, -k)
            sharp = sharp - k
        d = ctx.d_e[spoke_edges]
        equal = bool(np.all(np.abs(d - d[0]) <= 1e-12 * d.max()))
        if kind == CREASE:
            sizes = np.diff(np.append(sharp, sharp[0] + n)) if not boundary else [f]
            if min(sizes) == 1:
                continue
        if equal and not (kind == DART and n != 4):
            continue
        if d.min() <= 0.0:  # a zero interval (multiple knot): knot insertion on the boundary
            if not boundary and d.max() > 0.0:
                _refuse_tagged_on_zero(ctx, v, kind, spoke_edges, sharp, d)
            continue
        cols = np.concatenate([[v], ends, ctx.dest[ctx.nxt[ring]]])
        targets = np.concatenate([[ctx.nf + ctx.ne + v], ctx.nf + spoke_edges, ctx.face[ring]])
        key = (kind, n, tuple(sharp.tolist()), boundary)
        groups.setdefault(key, []).append((v, d, cols, targets, equal))
    for (kind, n, sharp, boundary), members in groups.items():
        d = np.array([mm[1] for mm in members])
        try:  # every rule is invariant under d -> s d: scaled to maximum 1
            m, defined, _, _ = tagged_rules_batch(kind, d / d.max(axis=1, keepdims=True), sharp, boundary)
        except BilinearError as exc:
            v, dv = members[exc.index[0]][:2]
            raise UnsupportedError(
                f"seed 000's eigen-polyhedron rule undefined at tagged vertex {v} (valence {n}, "
                f"spoke intervals {dv.tolist()}): {exc}",
                ctx.mesh.where("vertex", v),
            ) from None
        cols = np.array([mm[2] for mm in members])
        targets = np.array([mm[3] for mm in members])
        # a dart of valence != 4 with equal spokes: only its vertex row
        use = np.where(np.array([mm[4] for mm in members])[:, None], np.arange(defined.size) == 0, defined)
        gi, ri = np.nonzero(use)
        claims.add(targets[gi, ri], cols[gi], m[gi, ri])


def _refuse_tagged_on_zero(ctx: _Context, v: int, kind: int, spoke_edges: np.ndarray,
                           sharp: np.ndarray, d: np.ndarray) -> None:
    """An interior tagged vertex (dart, crease or corner; here infinitely sharp, since
    ``_refuse_semi_sharp_on_zero`` has refused the semi-sharp ones) with a spoke of knot
    interval 0 among others that are not.

    With the zero spoke at eps > 0 the eigen-polyhedron rules of ``tagged_rules_batch`` apply;
    they converge as eps -> 0 (``tagged_rules_batch`` takes zero spokes and gives the limit,
    error O(eps)), but the limit does not keep the zero strip degenerate: its spoke has length
    ``l_k > 0`` in the polyhedron, so the refined points across the strip stop coinciding.
    Knot insertion (what the vertex took before) keeps the strip degenerate but is another
    rule, 0.97 x size away from the eps limit (torus 12 x 10, one zero strip, a ring of
    infinitely sharp creases beside it, a semi-sharp crease elsewhere that makes
    ``build_operator`` subdivide).  Neither is right: with the limit rules the patches beside
    the strip do not close up (the strip's faces give no patch, and after two steps a run of
    four zero strips is a tear: gaps of 0.05 x size, an invalid B-rep even after one step), so
    the vertex is refused in one line naming the zero edge.  Open boundaries are not refused:
    a clamped side (DESIGN 2) keeps knot insertion, which is exactly the clamped NURBS.  Fires
    on the user's mesh (the first step): a later step gives no tagged vertex a zero spoke
    unless the vertex, or the ends of its crease edge, had one already."""
    zero = np.flatnonzero(d == 0.0)
    a, b = (int(x) for x in ctx.edges[spoke_edges[zero[0]]])
    if sharp.size:
        c0, c1 = (int(x) for x in ctx.edges[spoke_edges[sharp[0]]])
        tag = f"sharp crease {c0}-{c1} ({KINDS[kind]} vertex {v})"
    else:
        tag = f"sharp corner {v}"
    raise UnsupportedError(
        f"knot interval 0 on edge {a}-{b} at the {tag}: sharp features next to zero knot "
        f"intervals are subdivided only on open boundaries (clamped sides) so far",
        ctx.mesh.where("interval", (min(a, b), max(a, b))),
    )


# ------------------------------------------------------------------------------------------
# The operator


def _check_options(rules: str, angles: str, crease_method: str = "uniform") -> None:
    if rules not in RULE_SETS:
        raise UnsupportedError(f"unknown subdivision rules '{rules}' (choose {' or '.join(RULE_SETS)})")
    if angles not in ANGLE_CHOICES:
        raise UnsupportedError(f"unknown eigen-polyhedron angles '{angles}' (choose {' or '.join(ANGLE_CHOICES)})")
    if crease_method not in CREASE_METHODS:
        raise UnsupportedError(
            f"unknown crease method '{crease_method}' (choose {' or '.join(CREASE_METHODS)})"
        )
    if crease_method == "chaikin" and rules != "opensubdiv":
        raise UnsupportedError(
            "chaikin creasing is an option of OpenSubdiv's rules (use rules opensubdiv); seed "
            "000 decrements sharpness uniformly"
        )


def _refuse_nonuniform(ctx: _Context) -> None:
    si = ctx.topo.strip_interval
    e = int(np.flatnonzero(si[ctx.topo.edge_strip] != si[ctx.topo.edge_strip[0]])[0])
    a, b = ctx.edges[e]
    raise KnotError(
        f"opensubdiv rules need uniform knot intervals, but edge {a}-{b} has {ctx.d_e[e]:g} "
        f"and edge {ctx.edges[0, 0]}-{ctx.edges[0, 1]} has {ctx.d_e[0]:g} (use --rules seed)",
        ctx.mesh.where("interval", (int(a), int(b))),
    )


def _operator(ctx: _Context, rules: str, angles: str) -> sp.csr_matrix:
    seed = rules == "seed"
    if rules == "opensubdiv" and not ctx.uniform:
        _refuse_nonuniform(ctx)
    nonuniform = not ctx.uniform
    par = ctx.parent
    rows = _Rows()
    n_out = ctx.nf + ctx.ne + ctx.nv

    # Extraordinary points handled by the eigen-polyhedron (non-uniform only).
    claims = _Claims(n_out)
    if nonuniform:
        _check_nonuniform_support(ctx, seed)
        eps = np.flatnonzero(
            ~ctx.v_boundary
            & (ctx.valence != 4)
            & (ctx.valence > 2)  # valence 2: knot insertion and [LFS16]'s vertex rule (docstring)
            & (par.rule == SMOOTH)
            & ctx.topo.vertex_is_used
        )
        _ep_rows(ctx, eps, angles, claims)
        if seed:
            _tagged_rows(ctx, claims)
    claimed = claims.count > 0

    # Face points.
    _face_rows(ctx, rows, ~claimed[: ctx.nf])

    # Edge points: w sharp + (1 - w) smooth (scheme.h ComputeEdgeVertexMask; w = min(s, 1)
    # under uniform creasing, see _Context.edge_sharp_weight).
    w = ctx.edge_sharp_weight
    free_e = ~claimed[ctx.nf : ctx.nf + ctx.ne]
    sharp_e = np.flatnonzero((w > 0) & free_e)
    _sharp_edge_rows(ctx, rows, sharp_e, w[sharp_e], seed)
    smooth_e = np.flatnonzero((w != 1) & free_e)
    scale = 1.0 - w[smooth_e]
    if nonuniform:
        near_nonquad = ctx.v_nonquad[ctx.edges[smooth_e, 0]] & ctx.v_nonquad[ctx.edges[smooth_e, 1]]
        near_nonquad |= _edge_touches_nonquad(ctx, smooth_e)
        _cc_edge_rows(ctx, rows, smooth_e[near_nonquad], scale[near_nonquad])
        _tensor_edge_rows(ctx, rows, smooth_e[~near_nonquad], scale[~near_nonquad])
    else:
        _cc_edge_rows(ctx, rows, smooth_e, scale)
    if seed:
        # BLZ gamma: parent tags for smooth edges, child tags for the smooth part of a
        # fractional edge (whose own tag goes away).
        frac = (w[smooth_e] > 0)
        _blz_edge_correction(ctx, rows, par, smooth_e[~frac], scale[~frac])
        if frac.any():
            _blz_edge_correction(ctx, rows, ctx.child, smooth_e[frac], scale[frac])

    # Vertex points: parent rule, blended with the child rule (scheme.h ComputeVertexVertexMask).
    chi = ctx.child
    p_rule, c_rule = par.rule, chi.rule
    pw = _fractional_weight(ctx)
    blend = (p_rule > DART) & (c_rule != p_rule)
    sm_scale = np.where(p_rule <= DART, 1.0, np.where(blend & (c_rule <= DART), 1.0 - pw, 0.0))
    parent_scale = np.where(p_rule <= DART, 0.0, np.where(blend, pw, 1.0))
    child_scale = np.where(blend & (c_rule > DART), 1.0 - pw, 0.0)
    used = ctx.topo.vertex_is_used
    free_v = ~claimed[ctx.nf + ctx.ne :] & used
    vs_ = np.flatnonzero((sm_scale > 0) & free_v)
    if nonuniform:
        cc = ctx.v_nonquad[vs_]
        odd = ~cc & ((ctx.valence[vs_] != 4) | ctx.v_boundary[vs_])
        _lfs_vertex_rows(ctx, rows, vs_[odd], sm_scale[vs_[odd]])
        vs_, cc = vs_[~odd], cc[~odd]
        _cc_vertex_rows(ctx, rows, vs_[cc], sm_scale[vs_[cc]])
        _tensor_vertex_rows(ctx, rows, vs_[~cc], sm_scale[vs_[~cc]])
    else:
        _cc_vertex_rows(ctx, rows, vs_, sm_scale[vs_])
    # parent crease / corner part
    pc = np.flatnonzero((p_rule == CREASE) & (parent_scale > 0) & free_v)
    _crease_vertex_rows(ctx, rows, par, pc, parent_scale[pc], seed)
    pk = np.flatnonzero((p_rule == CORNER) & (parent_scale > 0) & free_v)
    rows.add(ctx.nf + ctx.ne + pk, pk, parent_scale[pk])
    # child crease / corner part (transition)
    cc_ = np.flatnonzero((c_rule == CREASE) & (child_scale > 0) & free_v)
    _crease_vertex_rows(ctx, rows, chi, cc_, child_scale[cc_], seed)
    ck = np.flatnonzero((c_rule == CORNER) & (child_scale > 0) & free_v)
    rows.add(ctx.nf + ctx.ne + ck, ck, child_scale[ck])
    # isolated vertices stay where they are
    iso = np.flatnonzero(~used)
    rows.add(ctx.nf + ctx.ne + iso, iso, 1.0)

    # EP and tagged-vertex rows (mean of the claims).
    claims.emit(rows)
    return rows.matrix((n_out, ctx.nv))


def _lfs_vertex_rows(ctx: _Context, rows: _Rows, v: np.ndarray, scale: np.ndarray) -> None:
    """[LFS16]'s vertex rule (``eigen_polyhedron.vertex_rule_weights``) for smooth vertices of
    valence != 4 that no EP solve claimed: a semi-sharp vertex whose tags fade this step, an
    interior vertex of valence 2 (Catmull-Clark's mask there, module docstring)."""
    from . import eigen_polyhedron as eig

    for vv, sc in zip(v.tolist(), scale.tolist()):
        ring = ctx.topo.one_ring(vv)
        if ctx.v_boundary[vv] or ring.size < 2:
            raise UnsupportedError(
                f"non-uniform intervals at vertex {vv} (valence {int(ctx.valence[vv])}): no "
                f"smooth rule for it",
                ctx.mesh.where("vertex", vv),
            )
        cols = np.concatenate([[vv], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
        # valence 2: the rule does not depend on the intervals (zero ones included)
        d = ctx.d_h[ring] if ring.size > 2 else np.ones(2)
        rows.add(ctx.nf + ctx.ne + vv, cols, sc * eig.vertex_rule_weights(d))


def _edge_touches_nonquad(ctx: _Context, e: np.ndarray) -> np.ndarray:
    h = ctx.topo.edge_halfedge[e]
    t = ctx.twin[h]
    return (ctx.ksize[h] != 4) | ((t >= 0) & (ctx.ksize[np.maximum(t, 0)] != 4))


def _fractional_weight(ctx: _Context) -> np.ndarray:
    """Crease::ComputeFractionalWeightAtVertex, (v,) float64: the mean parent sharpness of the
    vertex (if it decays to 0) and of its edges whose half at the vertex decays to 0 (uniform
    creasing: the edges of sharpness <= 1), clamped to 1."""
    total = np.zeros(ctx.nv)
    count = np.zeros(ctx.nv)
    vt = (ctx.vs > 0) & (_decrement(ctx.vs) <= 0)
    total[vt] += ctx.vs[vt]
    count[vt] += 1
    for k in (0, 1):
        et = (ctx.es > 0) & (ctx.child_es[:, k] <= 0)
        np.add.at(total, ctx.edges[et, k], ctx.es[et])
        np.add.at(count, ctx.edges[et, k], 1.0)
    return np.where(count > 0, np.minimum(1.0, total / np.maximum(count, 1.0)), 0.0)


def _check_nonuniform_support(ctx: _Context, seed: bool) -> None:
    """Refuse what the non-uniform rules here do not define (module docstring)."""
    # Non-quad faces: the child's strips must stay consistent.
    h = np.flatnonzero(ctx.ksize != 4)
    bad = h[ctx.d_h[ctx.nxt[h]] != ctx.d_h[ctx.prv[h]]]
    if bad.size:
        f = int(ctx.face[bad[0]])
        raise UnsupportedError(
            f"face {f} has {int(ctx.fsize[f])} sides and unequal knot intervals: the new edges "
            f"inside it would join strips of different intervals (give its edges equal "
            f"intervals, alternating for even sides)",
            ctx.mesh.where("face", f),
        )
    if seed:
        _refuse_semi_sharp_on_zero(ctx)


def _refuse_semi_sharp_on_zero(ctx: _Context) -> None:
    """A semi-sharp crease or corner (0 < s < 10) at a vertex with a spoke of knot interval 0.

    With a spoke interval eps > 0 the generalised eigen-polyhedron (``_tagged_rows``) gives the
    face points around such a vertex and the points of its untagged spokes, and those rows
    converge as eps -> 0 (error about eps: the rules are finite at 0 for one zero spoke); at 0
    ``_tagged_rows`` leaves the vertex to knot insertion, whose interval beyond it is the zero
    one mirrored (``ahead``): another rule, so S jumps (torus with one zero strip and an edge
    of s = 1 on its side: face 0 from {0: 7/16, 1: 1/16, 10: 7/16, 11: 1/16} at eps = 1e-9 to
    {10: 1/2, 11: 1/2}) and the patches fold.  Refused, never a wrong surface, until the
    eigen-polyhedron is evaluated at zero spokes.  Checked on the mesh given: a step gives no
    semi-sharp vertex a zero spoke unless its parent had one (the children of a semi-sharp
    edge halve the intervals of the spokes at its ends), so within ``build_operator``'s steps
    this fires on the first one, naming the user's ids."""
    semi_edge = (ctx.es > 0) & np.isfinite(ctx.es)
    semi_vertex = (ctx.vs > 0) & np.isfinite(ctx.vs)
    semi_vertex[ctx.edges[semi_edge].ravel()] = True
    bad = np.flatnonzero((ctx.d_e == 0) & semi_vertex[ctx.edges].any(axis=1))
    if bad.size == 0:
        return
    a, b = (int(x) for x in ctx.edges[bad[0]])
    v = a if semi_vertex[a] else b
    crease = np.flatnonzero(semi_edge & (ctx.edges == v).any(axis=1))
    if crease.size:
        c0, c1 = (int(x) for x in ctx.edges[crease[0]])
        tag = f"semi-sharp crease {c0}-{c1} (sharpness {ctx.es[crease[0]]:g})"
    else:
        tag = f"semi-sharp corner {v} (sharpness {ctx.vs[v]:g})"
    raise UnsupportedError(
        f"knot interval 0 on edge {a}-{b} at the {tag}: semi-sharp tags next to zero knot "
        "intervals are not supported yet",
        ctx.mesh.where("interval", (min(a, b), max(a, b))),
    )


# ------------------------------------------------------------------------------------------
# The refined mesh and its tags


def _child_mesh(ctx: _Context, points: np.ndarray) -> ControlMesh:
    nf, ne = ctx.nf, ctx.ne
    h = np.arange(ctx.H)
    quads = np.stack(
        [nf + ne + ctx.origin, nf + ctx.eoh, ctx.face, nf + ctx.eoh[ctx.prv]], axis=1
    ).astype(np.int64)
    n_child = nf + ne + ctx.nv
    # Child edges: halves of parent edges (interval d/2, sharpness decremented) and the edges
    # F(face h) - E(edge h) inside a face (interval of the parallel parent edge, next(h), / 2).
    a, b = ctx.edges[:, 0], ctx.edges[:, 1]
    half_pairs = np.concatenate(
        [np.stack([nf + ne + a, nf + np.arange(ne)], 1), np.stack([nf + ne + b, nf + np.arange(ne)], 1)]
    )
    half_d = np.concatenate([ctx.d_e, ctx.d_e]) / 2.0
    inner_pairs = np.stack([ctx.face, nf + ctx.eoh], 1)
    inner_d = ctx.d_h[ctx.nxt[h]] / 2.0
    creases = {}
    es_child = ctx.child_es
    parent_s = ctx.topo.edge_sharpness
    for k, end in enumerate((a, b)):
        keep = np.flatnonzero((es_child[:, k] > 0) & ~ctx.e_boundary)
        for e in keep.tolist():
            s = float(parent_s[e]) if parent_s[e] >= INFINITELY_SHARP else float(es_child[e, k])
            pair = (nf + ne + int(end[e]), nf + e)
            creases[(min(pair), max(pair))] = s
    corners = {}
    for v, s in ctx.mesh.corners.items():
        if s >= INFINITELY_SHARP:
            corners[nf + ne + v] = float(s)
        elif s > 1.0:
            corners[nf + ne + v] = float(s) - 1.0
    holes = frozenset(int(x) for x in h[np.isin(ctx.face, np.fromiter(ctx.mesh.holes, np.int64))]) if ctx.mesh.holes else frozenset()
    child = ControlMesh(
        vertices=np.ascontiguousarray(points, dtype=np.float64),
        face_vertices=quads.ravel(),
        face_offsets=np.arange(0, 4 * ctx.H + 1, 4, dtype=np.int64),
        intervals={},
        creases=creases,
        corners=corners,
        holes=holes,
        interpolate_boundary=ctx.mesh.interpolate_boundary,
        name=ctx.mesh.name,
    )
    # One interval per child strip (DESIGN 2: a value on one edge applies to its strip).
    ct = Topology(child)
    pairs = np.concatenate([half_pairs, inner_pairs])
    dvals = np.concatenate([half_d, inner_d])
    lo, hi = pairs.min(1), pairs.max(1)
    keys = ct.edges[:, 0] * n_child + ct.edges[:, 1]
    idx = np.searchsorted(keys, lo * n_child + hi)
    strip = ct.edge_strip[idx]
    first = np.full(ct.n_strips, -1, np.int64)
    first[strip[::-1]] = np.arange(strip.size)[::-1]
    value = dvals[first[strip]]
    if not np.allclose(value, dvals, rtol=1e-12, atol=0):
        raise AssertionError("child strips with two intervals (a bug: the non-quad check missed it)")
    reps = first[first >= 0]
    intervals = {(int(lo[i]), int(hi[i])): float(dvals[i]) for i in reps.tolist()}
    return replace(child, intervals=intervals)


@one_blas_thread
def subdivision_operator(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str = "uniform"
) -> tuple[sp.csr_matrix, ControlMesh]:
    """One subdivision step: (S, refined mesh).

    S: (n_faces + n_edges + n_vertices, n_vertices) CSR float64, rows sum to 1, built from
    topology, intervals and tags only; refined points = ``S @ mesh.vertices`` (child numbering in
    the module docstring).  The refined mesh carries the tags: intervals halved (one value per
    strip), crease and corner sharpness decremented (infinite stays), holes' children holes,
    interpolateboundary; its positions are ``S @ mesh.vertices``.
    rules: "seed" (default) or "opensubdiv"; angles: "standard" or "modified" (seed 001, for
    the eigen-polyhedron at non-uniform extraordinary points); crease_method: "uniform"
    (default: sharpness drops by 1) or "chaikin" (OpenSubdiv's ``CREASE_CHAIKIN``, with
    ``rules="opensubdiv"`` only: the two halves of a semi-sharp edge get ``3/4 s + 1/4 (mean
    of the other semi-sharp edges at that end) - 1``, see ``_chaikin``; the refined mesh's
    crease tags carry each half's value).
    Raises KnotError for non-uniform intervals under "opensubdiv", UnsupportedError for the
    configurations listed in the module docstring, MeshError for non-manifold input.
    """
    _check_options(rules, angles, crease_method)
    ctx = _Context(mesh, crease_method)
    s = _operator(ctx, rules, angles)
    child = _child_mesh(ctx, s @ mesh.vertices)
    return s, child


#: Largest mesh ``subdivide`` makes: measured 1.4 kB of peak memory per face (cube, 8 steps:
#: 393k faces, 0.56 GB, 6 s), so 5.6 GB; 40 steps of a cube were killed for memory before.
MAX_SUBDIVIDE_FACES = 4_000_000


def subdivide(
    mesh: ControlMesh, steps: int = 1, rules: str = "seed", angles: str = "standard", crease_method: str = "uniform"
) -> ControlMesh:
    """``steps`` subdivision steps; the refined control mesh with its tags (options as
    :func:`subdivision_operator`)."""
    _check_options(rules, angles, crease_method)
    if steps < 0:
        raise UnsupportedError(f"number of subdivision steps must be >= 0, got {steps}")
    # The first step turns every n-gon into n quads, each later step a quad into four.
    faces = int(mesh.face_sizes.sum()) * 4 ** (steps - 1) if steps else mesh.n_faces
    if faces > MAX_SUBDIVIDE_FACES:
        raise UnsupportedError(
            f"{steps} subdivision steps of {mesh.n_faces} faces make {faces:.3g} faces, more than "
            f"{MAX_SUBDIVIDE_FACES:,} (about 1.4 kB of memory each): take fewer steps",
            mesh.name,
        )
    for _ in range(steps):
        _, mesh = subdivision_operator(mesh, rules, angles, crease_method)
    return mesh


# ------------------------------------------------------------------------------------------
# Limit points and tangents


#: Most steps ``limit_operator`` takes to let semi-sharp features decay (1 + ceil(sharpness)).
MAX_LIMIT_STEPS = 6
#: Largest refined mesh (faces) ``limit_operator`` builds on the way.
MAX_LIMIT_FACES = 4_000_000


def _refine_for_limit(mesh: ControlMesh, rules: str, angles: str, crease_method: str = "uniform"):
    """Subdivide until every rule is stationary: one step (so that every vertex sees equal
    intervals on both halves of each spoke, seed 000 Fig. 8) plus one per unit of the largest
    finite sharpness.  Returns (level mesh, S_total, ids of the input vertices at that level)."""
    finite = [x for x in list(mesh.creases.values()) + list(mesh.corners.values()) if x < INFINITELY_SHARP]
    steps = 1 + int(math.ceil(max(finite, default=0.0)))
    if steps > MAX_LIMIT_STEPS or mesh.n_faces * 4**steps > MAX_LIMIT_FACES:
        raise UnsupportedError(
            f"limit of a semi-sharp feature of sharpness {max(finite):g} needs {steps} steps "
            f"({mesh.n_faces * 4**steps} faces); this version takes at most {MAX_LIMIT_STEPS} "
            f"steps and {MAX_LIMIT_FACES} faces",
            mesh.name,
        )
    total = sp.identity(mesh.n_vertices, format="csr")
    ids = np.arange(mesh.n_vertices)
    for _ in range(steps):
        ctx = _Context(mesh, crease_method)
        s = _operator(ctx, rules, angles)
        total = (s @ total).tocsr()
        ids = ctx.nf + ctx.ne + ids
        mesh = _child_mesh(ctx, s @ mesh.vertices)
    return mesh, total, ids


def _spokes(ctx: _Context, v: np.ndarray):
    s0 = ctx.topo.outgoing[v]
    s1 = ctx.topo.rotate(s0)
    s2 = ctx.topo.rotate(s1)
    s3 = ctx.topo.rotate(s2)
    return s0, s1, s2, s3


def _local_masks(ctx: _Context, ids: np.ndarray, rules: str, angles: str, tangents: bool):
    """Limit (or tangent) masks at vertices ``ids`` of a stationary level: lists of
    (row-of-ids, cols, weights) triplets for position, tangent 1, tangent 2; and a mask of the
    rows whose tangents are undefined (corners, creases across, seed-rule darts of valence != 4)."""
    from . import eigen_polyhedron as eig

    lev = ctx.parent
    rule = lev.rule[ids]
    out = [_Rows(), _Rows(), _Rows()]
    undefined = np.zeros((ids.size, 2), bool)
    k = np.arange(ids.size)

    corner = rule == CORNER
    out[0].add(k[corner], ids[corner], 1.0)
    undefined[corner] = True

    cr = np.flatnonzero(rule == CREASE)
    if cr.size:
        v = ids[cr]
        e0, e1 = lev.crease_edges[v, 0], lev.crease_edges[v, 1]
        end0 = np.where(ctx.edges[e0, 0] == v, ctx.edges[e0, 1], ctx.edges[e0, 0])
        end1 = np.where(ctx.edges[e1, 0] == v, ctx.edges[e1, 1], ctx.edges[e1, 0])
        a, b = ctx.d_e[e0], ctx.d_e[e1]
        for rows, w in ((out[0], curve_limit_weights(a, b)), (out[1], curve_derivative_weights(a, b))):
            rows.add(cr, end0, w[0])
            rows.add(cr, v, w[1])
            rows.add(cr, end1, w[2])
        undefined[cr, 1] = True

    # Darts under seed rules: the edges and faces around them are BLZ- or seed-000-modified,
    # so the local matrix is neither Catmull-Clark's nor a tensor product: take the dominant
    # left eigenvector of S's own 1-ring block (closed at a stationary level).
    seed_dart = (rule == DART) & (rules == "seed")
    for i in np.flatnonzero(seed_dart).tolist():
        v = int(ids[i])
        ring = ctx.topo.one_ring(v)
        cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
        block = _ring_block(ctx, v, ring, rules, angles)
        w, vl = np.linalg.eig(block.T)
        j = int(np.argmin(np.abs(w - 1.0)))
        lim = np.real(vl[:, j])
        out[0].add(np.full(cols.size, i), cols, lim / lim.sum())
        undefined[i] = True
    smooth = (rule <= DART) & ~seed_dart
    reg = np.flatnonzero(smooth & (ctx.valence[ids] == 4) & ~ctx.v_boundary[ids])
    if reg.size:
        v = ids[reg]
        spokes = _spokes(ctx, v)
        d = [ctx.d_h[h] for h in spokes]
        E = [ctx.dest[h] for h in spokes]
        F = [ctx.dest[ctx.nxt[h]] for h in spokes]
        limA, limB = curve_limit_weights(d[2], d[0]), curve_limit_weights(d[3], d[1])
        derA, derB = curve_derivative_weights(d[2], d[0]), curve_derivative_weights(d[3], d[1])
        for rows, wa, wb in ((out[0], limA, limB), (out[1], derA, limB), (out[2], limA, derB)):
            mA, cA, pA = wa
            mB, cB, pB = wb
            rows.add(reg, v, cA * cB)
            rows.add(reg, E[0], pA * cB)
            rows.add(reg, E[2], mA * cB)
            rows.add(reg, E[1], cA * pB)
            rows.add(reg, E[3], cA * mB)
            rows.add(reg, F[0], pA * pB)
            rows.add(reg, F[1], mA * pB)
            rows.add(reg, F[2], mA * mB)
            rows.add(reg, F[3], pA * mB)

    odd = np.flatnonzero(smooth & (ctx.valence[ids] != 4) & ~ctx.v_boundary[ids])
    for i in odd.tolist():
        v = int(ids[i])
        ring = ctx.topo.one_ring(v)
        n = ring.size
        cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
        d = ctx.d_h[ring]
        if n == 2:  # Catmull-Clark's 1-ring matrix at any intervals (module docstring)
            out[0].add(np.full(cols.size, i), cols, np.array([2.0, 2.0, 2.0, 0.5, 0.5]) / 7.0)
            undefined[i] = True
            continue
        if ctx.uniform:  # Catmull-Clark's limit mask (OpenSubdiv's assignSmoothLimitMask)
            lim = np.concatenate([[n / (n + 5.0)], np.full(n, 4.0 / (n * (n + 5.0))), np.full(n, 1.0 / (n * (n + 5.0)))])
        else:
            lim = eig.limit_point_weights(d, angles=angles)
        out[0].add(np.full(cols.size, i), cols, lim)
        if tangents:
            tw = eig.tangent_weights(d if not ctx.uniform else np.ones(n), angles=angles)
            out[1].add(np.full(cols.size, i), cols, tw[0])
            out[2].add(np.full(cols.size, i), cols, tw[1])
    return out, undefined


def _ring_block(ctx: _Context, v: int, ring: np.ndarray, rules: str, angles: str) -> np.ndarray:
    """S's rows and columns of v's 1-ring [V, E_0.., F_0..] (S built once per level)."""
    ops = ctx.__dict__.setdefault("_operators", {})
    if (rules, angles) not in ops:
        ops[(rules, angles)] = _operator(ctx, rules, angles)
    s = ops[(rules, angles)]
    cols = np.concatenate([[v], ctx.dest[ring], ctx.dest[ctx.nxt[ring]]])
    rows = np.concatenate([[ctx.nf + ctx.ne + v], ctx.nf + ctx.eoh[ring], ctx.face[ring]])
    return s[rows][:, cols].toarray()


def limit_operator(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str = "uniform"
) -> sp.csr_matrix:
    """L: (n_vertices, n_vertices) CSR, ``L @ P`` = the limit-surface point of every vertex.

    Subdivides until the rules are stationary (``_refine_for_limit``), then applies the local
    limit masks: corner ``V``; crease ``curve_limit_weights`` along the crease (uniform
    (1, 4, 1)/6); regular smooth vertex the tensor product of the curve limit masks (the
    NURBS point); uniform EP Catmull-Clark's ``(n^2 V + 4 sum E + sum F) / (n (n + 5))``;
    non-uniform EP the dominant left eigenvector of the eigen-polyhedron matrix
    (``eigen_polyhedron.limit_point_weights``, seed 002 section 3.5 step 2); a seed-rule dart
    of valence != 4 (BLZ-modified edges) the left eigenvector of S's own 1-ring block.
    Isolated vertices: themselves.
    """
    _check_options(rules, angles, crease_method)
    level, total, ids = _refine_for_limit(mesh, rules, angles, crease_method)
    ctx = _Context(level)
    used = ctx.topo.vertex_is_used[ids]
    (pos, _, _), _ = _local_masks(ctx, ids[used], rules, angles, tangents=False)
    lim = (pos.matrix((int(used.sum()), level.n_vertices)) @ total).tocoo()
    rows_used = np.flatnonzero(used)
    iso = np.flatnonzero(~used)
    r = np.concatenate([rows_used[lim.row], iso])
    c = np.concatenate([lim.col, iso])
    v = np.concatenate([lim.data, np.ones(iso.size)])
    return sp.csr_matrix((v, (r, c)), shape=(mesh.n_vertices, mesh.n_vertices))


def limit_points(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str = "uniform"
) -> np.ndarray:
    """(n_vertices, 3) limit-surface position of every control vertex (``limit_operator``)."""
    return limit_operator(mesh, rules, angles, crease_method) @ mesh.vertices


def limit_tangents(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str = "uniform"
) -> np.ndarray:
    """(n_vertices, 2, 3) two tangent vectors of the limit surface at every vertex; NaN where the
    surface has no single tangent plane or this version does not compute it (corners; the
    second vector at crease vertices, where only the crease direction is given; seed-rule darts
    of valence != 4; interior vertices of valence 2, where Catmull-Clark's eigenvalue -1/4
    matches the subdominant 1/4 in modulus; isolated vertices).

    Regular vertex: parametric derivatives of the NURBS limit along the spokes ``E_0`` and
    ``E_1`` (``curve_derivative_weights``; first x second points along the faces' normal).
    EP: ``eigen_polyhedron.tangent_weights`` (derivatives along the eigen-polyhedron's axes,
    Catmull-Clark's eigenvectors for uniform intervals).  Crease: the derivative along the
    crease curve, from its first crease edge to its second.
    """
    _check_options(rules, angles, crease_method)
    level, total, ids = _refine_for_limit(mesh, rules, angles, crease_method)
    ctx = _Context(level)
    used = ctx.topo.vertex_is_used[ids]
    rows_used = np.flatnonzero(used)
    (_, t1, t2), undefined = _local_masks(ctx, ids[used], rules, angles, tangents=True)
    out = np.full((mesh.n_vertices, 2, 3), np.nan)
    P = total @ mesh.vertices
    for j, rows in enumerate((t1, t2)):
        vec = rows.matrix((rows_used.size, level.n_vertices)) @ P
        vec[undefined[:, j]] = np.nan
        out[rows_used, j] = vec
    return out
