"""One step of Catmull-Clark subdivision as a sparse operator, uniform or non-uniform, with sharp
and semi-sharp features ([TLC], [ZTL], [FSLYJ] Appendix).

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

Three rule sets (``rules``):

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
  (``patching.rules.crease``, shared with Loop: each half of an edge from the semi-sharp
  edges at its end; the edge and vertex blends then read the halves, as
  ``Far::PrimvarRefiner`` does).  With the mesh's ``triangle_subdivision="smooth"`` (the
  OBJ tag ``t smoothtriangles 0/0/1 smooth``, [OSD]'s ``TRI_SUB_SMOOTH``) the smooth edge
  point of an edge of two faces, at least one a triangle, is ``(1/2 - f)(a + b) + f (F_0 +
  F_1)`` with f the mean of 0.47 per triangle and 1/4 per other face (``catmarkScheme.h``
  ``assignSmoothMaskForEdge``; face and vertex points unchanged, so only the first step
  differs); the other rule sets refuse it on a mesh with triangles.  Uniform intervals
  only: a non-uniform mesh is refused with a KnotError.
* ``"seed"`` (default): [TLC].  Uniform intervals: the Biermann-Levin-Zorin rules of its
  section 2 (the same vertex classification; an untagged edge next to a tagged vertex gets
  ``gamma = 3/8 - cos(theta)/4``, theta ``2 pi/m`` at a dart, ``pi/m`` at a crease, ``alpha/m``
  at a convex corner); semi-sharp sharpness handled exactly as under ``"opensubdiv"`` ([TLC]
  section 5 clears the tags after ``s`` steps; the fractional blend is OpenSubdiv's).
  Non-uniform intervals: midpoint knot insertion in regular regions (tensor products of the
  curve rules, ``subdivision_rules``), non-uniform cubic B-spline crease curves, and the
  eigen-polyhedron rules of [LFS16] (``eigen_polyhedron``, angles of [ZTL] with
  ``angles="modified"``) on faces and edges around an untagged extraordinary point.
* ``"nurss"``: the baseline of [TLC] and [ZTL], Sederberg et al.'s NURSS ([SZSS98]): as
  ``"seed"`` everywhere but at untagged non-uniform extraordinary points, whose 1-ring rows
  are NURSS's heuristic generalisation of knot insertion (``rules.nurss``) instead of the
  eigen-polyhedron's.  Uniform intervals: Catmull-Clark, as ``"seed"``.

Choices where the seeds are silent, written once:

* Corner sector angle ``alpha`` (BLZ: "the angle of the sector"): the sum of the corner angles
  ``pi (k - 2) / k`` of the sector's k-gons, a topological angle, so that ``S`` does not depend
  on positions; a quad sector of m faces gets ``theta = pi/2``, the standard rule (a cube's
  corner angles are exactly that).  Convex and concave sectors ([TLC] sec. 2: "convex
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
  image that [TLC] Fig. 8 assumes (``d-bar = d``).  With it a crease ending at a corner
  interpolates the corner and its first edge point is the midpoint, as [TLC]'s corner eigen-polyhedron (``P^1 = P^0 / 2``) requires.
* Zero intervals (multiple knots, docs/knots.md) split into two zero halves.  On a clamped side (an
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
* Non-uniform intervals at tagged vertices ([TLC] sec. 4): the generalised
  eigen-polyhedron rules (``subdivision_rules.tagged_rules_batch``) give the face points
  around the vertex, the edge points of its untagged spokes and a dart's vertex point; crease
  edges and crease/corner vertices follow the non-uniform crease curve.  Where a tagged
  vertex's spoke intervals are all equal, section 2's BLZ rule is kept instead (on top of knot
  insertion): section 4's edge form with equal intervals is not BLZ's rule when
  theta != pi/2 (tests record the difference), and the acceptance asks for section 2 there.
  A crease sector of a single face (theta = pi) makes the polyhedron degenerate: knot
  insertion with BLZ there too.  A zero spoke interval (a multiple knot, docs/knots.md): knot
  insertion on an open boundary (a clamped side, exactly the clamped NURBS); inside the mesh
  refused (``_refuse_tagged_on_zero``: the rules' eps -> 0 limit exists, but it opens the
  zero strip and the patches beside it do not close up).
* An interior vertex of valence 2 with non-uniform intervals (two quads sharing two edges).
  The eigen-polyhedron of [TLC] sec. 3 needs n >= 3 (at n = 2, ``c_n = -1`` and
  ``tau = 4 / (c_n + 1 + sqrt((c_n + 9)(c_n + 1)))`` is infinite: the two spokes are opposite
  and the face points collapse onto V), so no face or edge rule comes from a solve there.
  What the seeds do define: the vertex rule of [LFS16] ([FSLYJ] eq. 11, [TLC] eqs. 6-7)
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

from functools import cached_property

import numpy as np
import scipy.sparse as sp

from patching.util.blas import one_blas_thread
from patching.errors import KnotError, UnsupportedError
from patching.mesh.control_mesh import ControlMesh
from patching.rules.catmark import (
    CORNER,
    KINDS,
    CREASE,
    DART,
    SMOOTH,
    blz_gamma,
    curve_edge_weights,
    curve_vertex_weights,
    tagged_rules_batch,
)
from patching.rules.crease import CREASE_METHODS, crease_method_of, decrement
from patching.subdivision.child_mesh import _child_mesh
from patching.subdivision.context import _Context, _Level
from patching.subdivision.quad_rows import quad_operator
from patching.util.sparse_rows import TripletRows

__all__ = [
    "subdivide",
    "subdivision_operator",
    "rules_tag",
    "RULE_SETS",
    "ANGLE_CHOICES",
    "CREASE_METHODS",
]

RULE_SETS = ("seed", "opensubdiv", "nurss")
ANGLE_CHOICES = ("standard", "modified")
#: Name of the OBJ tag that records the rule set: ``t nupatch_rules 0/0/1 seed``.
RULES_TAG = "nupatch_rules"


def rules_tag(rules: str) -> str:
    """The OBJ tag line recording the rule set of a subdivided mesh."""
    return f"t {RULES_TAG} 0/0/1 {rules}"


# ------------------------------------------------------------------------------------------
# Rows


def _face_rows(ctx: _Context, rows: TripletRows, faces_mask: np.ndarray) -> None:
    """Face points: centroid (uniform, non-quads) or the tensor product of the curve edge rules
    (non-uniform quads: the bilinear form of [TLC] eq. 18 with knot-insertion weights)."""
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


def _cc_edge_rows(ctx: _Context, rows: TripletRows, e: np.ndarray, scale: np.ndarray) -> None:
    """Catmull-Clark's smooth edge point (a + b + F_0 + F_1) / 4 (face points as centroids);
    beside a triangle with smooth triangles, ``(1/2 - f)(a + b) + f (F_0 + F_1)``
    (``_Context.smooth_edge_face_weight``)."""
    if e.size == 0:
        return
    sc = np.zeros(ctx.ne)
    sc[e] = scale
    fw = ctx.smooth_edge_face_weight
    row_e = ctx.nf + e
    vw = (0.5 - fw[e]) * scale
    rows.add(row_e, ctx.edges[e, 0], vw)
    rows.add(row_e, ctx.edges[e, 1], vw)
    ph, php = ctx.face_pairs
    sel = np.flatnonzero(sc[ctx.eoh[ph]] != 0)
    ph, php = ph[sel], php[sel]
    eh = ctx.eoh[ph]
    rows.add(ctx.nf + eh, ctx.origin[php], sc[eh] * fw[eh] / ctx.ksize[ph])


def _tensor_edge_rows(ctx: _Context, rows: TripletRows, e: np.ndarray, scale: np.ndarray) -> None:
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


def _blz_edge_correction(ctx: _Context, rows: TripletRows, lev: _Level, e: np.ndarray, scale) -> None:
    """BLZ's modification next to tagged vertices, as a correction of the standard rule:
    ``(3/8 - gamma)(tagged end - other end)`` (mean of the two when both ends are tagged)."""
    e, corr = _blz_terms(ctx, lev, e, scale)
    if e.size == 0:
        return
    h = ctx.topo.edge_halfedge[e]
    row = ctx.nf + e
    rows.add(row, ctx.origin[h], corr)
    rows.add(row, ctx.dest[h], -corr)


def _blz_terms(ctx: _Context, lev: _Level, e: np.ndarray, scale) -> tuple[np.ndarray, np.ndarray]:
    """(edges, corr): the edges of ``e`` with a tagged end and their BLZ correction, the weight
    added to ``origin(edge_halfedge)`` and taken from ``dest`` (``_blz_edge_correction``)."""
    h = ctx.topo.edge_halfedge[e]
    a, b = ctx.origin[h], ctx.dest[h]
    tag_a, tag_b = lev.rule[a] != SMOOTH, lev.rule[b] != SMOOTH
    keep = np.flatnonzero(tag_a | tag_b)  # the correction is 0 elsewhere
    if keep.size == 0:
        return keep, np.zeros(0)
    h, tag_a, tag_b = h[keep], tag_a[keep], tag_b[keep]
    t = ctx.twin[h]
    both = np.where(tag_a & tag_b, 0.5, 1.0)
    delta_a = np.where(tag_a, 0.375 - blz_gamma(ctx.theta_at(lev, h)), 0.0)
    delta_b = np.where(tag_b, 0.375 - blz_gamma(ctx.theta_at(lev, t)), 0.0)
    return e[keep], np.broadcast_to(scale, e.shape)[keep] * both * (delta_a - delta_b)


def _sharp_edge_rows(ctx: _Context, rows: TripletRows, e: np.ndarray, scale: np.ndarray, seed: bool) -> None:
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


def _cc_vertex_rows(ctx: _Context, rows: TripletRows, v: np.ndarray, scale: np.ndarray) -> None:
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


def _tensor_vertex_rows(ctx: _Context, rows: TripletRows, v: np.ndarray, scale: np.ndarray) -> None:
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


def _crease_vertex_rows(ctx: _Context, rows: TripletRows, lev: _Level, v: np.ndarray, scale, seed: bool) -> None:
    """Crease vertex: 3/4 V + 1/8 (ends) uniform; the curve vertex rule along the crease curve
    ([TLC] eq. 11) for non-uniform intervals."""
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

    def emit(self, out: TripletRows) -> None:
        for rows, cols, weights in self.blocks:
            out.add(rows[:, None], cols, weights / self.count[rows][:, None])


def _ep_rows(ctx: _Context, eps: np.ndarray, angles: str, claims: _Claims, rules: str = "seed") -> None:
    """Rows of the [LFS16] local matrix around every untagged EP, the EPs of one valence in one
    vectorised solve (``eigen_polyhedron.local_subdivision_matrices``); under ``rules="nurss"``
    NURSS's local matrix instead (``rules.nurss``, [SZSS98])."""
    from patching.rules import eigen_polyhedron as eig
    from patching.rules.nurss import nurss_local_matrices

    for n in np.unique(ctx.valence[eps]).tolist():
        v = eps[ctx.valence[eps] == n]
        ring = np.stack([ctx.topo.one_ring(x) for x in v.tolist()])  # (g, n) spokes
        d = ctx.d_h[ring]
        try:
            m = nurss_local_matrices(d) if rules == "nurss" else eig.local_subdivision_matrices(d, angles=angles)
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
    """[TLC] sec. 4 at tagged vertices (non-uniform): the generalised eigen-polyhedron
    rules of ``subdivision_rules.tagged_rules_batch`` claim the face points around the vertex,
    the edge points of its untagged spokes and (dart) its vertex point; vertices of one kind
    and shape are solved together.  Not used, so that the BLZ rules of section 2 apply there
    (on top of knot insertion): a vertex whose spoke intervals are all equal (section 4 with
    equal intervals is not section 2 for theta != pi/2, see the report in
    ``tagged_vertex_rules``' tests; a dart of valence != 4 still takes its vertex row, which is
    Catmull-Clark's then), a crease sector of one face (theta = pi, a degenerate polyhedron),
    and vertices next to a non-quad face."""
    from patching.rules.eigen_polyhedron import BilinearError

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
                f"[TLC]'s eigen-polyhedron rule undefined at tagged vertex {v} (valence {n}, "
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
    a clamped side (docs/knots.md) keeps knot insertion, which is exactly the clamped NURBS.  Fires
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


def _check_options(rules: str, angles: str, crease_method: str = "uniform", where: str | None = None) -> None:
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
            "000 decrements sharpness uniformly",
            where or "",
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


def _operator(ctx: _Context, rules: str, angles: str, canonical: bool = True) -> sp.csr_matrix:
    """S of one step.  canonical=False (``subdivide``'s own products) may leave explicit zeros
    and repeated columns in the rows of ``quad_operator``: the same products."""
    seed = rules in ("seed", "nurss")  # NURSS differs from [TLC]'s rules at smooth EPs only
    if rules == "opensubdiv" and not ctx.uniform:
        _refuse_nonuniform(ctx)
    if ctx.smooth_triangles and rules != "opensubdiv":
        raise UnsupportedError(
            f"smooth triangles (t smoothtriangles, OpenSubdiv's TRI_SUB_SMOOTH) are a rule of "
            f"--rules opensubdiv, not of rules {rules}: use --rules opensubdiv or --triangles catmark",
            ctx.mesh.where("tag", "smoothtriangles"),
        )
    if ctx.uniform:
        s = _uniform_quads(ctx, seed, canonical)
        return _triplet_operator(ctx, rules, angles) if s is None else s
    # the local solves at EPs and tagged vertices: many small dense problems (util.blas)
    return one_blas_thread(_triplet_operator)(ctx, rules, angles)


def _triplet_operator(ctx: _Context, rules: str, angles: str) -> sp.csr_matrix:
    """S gathered rule by rule as triplets (any faces, any intervals)."""
    seed = rules in ("seed", "nurss")
    nonuniform = not ctx.uniform
    par = ctx.parent
    rows = TripletRows()
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
        _ep_rows(ctx, eps, angles, claims, rules)
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
    sm_scale, parent_scale, child_scale = _vertex_scales(ctx)
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


def _uniform_quads(ctx: _Context, seed: bool, canonical: bool) -> sp.csr_matrix | None:
    """S of a uniform step of an all-quad mesh in CSR order (``quad_operator``): the rows
    ``_operator``'s triplets give, BLZ's edge correction included under the seed rules."""
    if not np.all(ctx.fsize == 4):
        return None
    w = ctx.edge_sharp_weight
    corr = np.zeros(ctx.ne)
    if seed:
        smooth_e = np.flatnonzero(w != 1)
        frac = w[smooth_e] > 0
        scale = 1.0 - w[smooth_e]
        for lev, sel in ((ctx.parent, ~frac), (ctx.child, frac)):
            e, c = _blz_terms(ctx, lev, smooth_e[sel], scale[sel])
            corr[e] += c
    return quad_operator(ctx, w, corr, _vertex_scales(ctx), canonical)


def _vertex_scales(ctx: _Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(v,) weights of the smooth, the parent's (crease or corner) and the child's rule in every
    vertex point (``Sdc::Scheme::ComputeVertexVertexMask``: a vertex whose rule changes this
    step blends the parent rule, by the fractional weight, with the child's)."""
    p_rule, c_rule = ctx.parent.rule, ctx.child.rule
    pw = _fractional_weight(ctx)
    blend = (p_rule > DART) & (c_rule != p_rule)
    sm_scale = np.where(p_rule <= DART, 1.0, np.where(blend & (c_rule <= DART), 1.0 - pw, 0.0))
    parent_scale = np.where(p_rule <= DART, 0.0, np.where(blend, pw, 1.0))
    child_scale = np.where(blend & (c_rule > DART), 1.0 - pw, 0.0)
    return sm_scale, parent_scale, child_scale


def _lfs_vertex_rows(ctx: _Context, rows: TripletRows, v: np.ndarray, scale: np.ndarray) -> None:
    """[LFS16]'s vertex rule (``eigen_polyhedron.vertex_rule_weights``) for smooth vertices of
    valence != 4 that no EP solve claimed: a semi-sharp vertex whose tags fade this step, an
    interior vertex of valence 2 (Catmull-Clark's mask there, module docstring)."""
    from patching.rules import eigen_polyhedron as eig

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
    vt = (ctx.vs > 0) & (decrement(ctx.vs) <= 0)
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


def subdivision_operator(
    mesh: ControlMesh, rules: str = "seed", angles: str = "standard", crease_method: str | None = None
) -> tuple[sp.csr_matrix, ControlMesh]:
    """One subdivision step: (S, refined mesh).

    S: (n_faces + n_edges + n_vertices, n_vertices) CSR float64, rows sum to 1, built from
    topology, intervals and tags only; refined points = ``S @ mesh.vertices`` (child numbering in
    the module docstring).  The refined mesh carries the tags: intervals halved (one value per
    strip), crease and corner sharpness decremented (infinite stays), holes' children holes,
    interpolateboundary; its positions are ``S @ mesh.vertices``.
    rules: "seed" (default), "opensubdiv" or "nurss"; angles: "standard" or "modified" ([ZTL], for
    the eigen-polyhedron at non-uniform extraordinary points); crease_method: "uniform"
    (default: sharpness drops by 1) or "chaikin" (OpenSubdiv's ``CREASE_CHAIKIN``, with
    ``rules="opensubdiv"`` only: the two halves of a semi-sharp edge get ``3/4 s + 1/4 (mean
    of the other semi-sharp edges at that end) - 1``, see ``patching.rules.crease``; the
    refined mesh's crease tags carry each half's value); None (default): the mesh's
    ``crease_method`` (its OBJ tag ``t creasemethod``, else "uniform"); the refined mesh
    carries the method used.  The mesh's ``triangle_subdivision``
    ("smooth": [OSD]'s ``TRI_SUB_SMOOTH``, module docstring) is a rule of "opensubdiv"; the
    other rule sets refuse it on a mesh with triangles (UnsupportedError).
    Raises KnotError for non-uniform intervals under "opensubdiv", UnsupportedError for the
    configurations listed in the module docstring, MeshError for non-manifold input.
    """
    crease_method = _resolve(mesh, rules, angles, crease_method)
    return _step(mesh, rules, angles, crease_method, canonical=True)


def _resolve(mesh: ControlMesh, rules: str, angles: str, crease_method: str | None) -> str:
    """The crease method to use (``crease_method_of``), options checked; a chaikin taken from
    the mesh and refused by ``rules`` names the tag's line."""
    where = mesh.locations.get(("tag", "creasemethod"), "crease_method") if crease_method is None else None
    crease_method = crease_method_of(mesh, crease_method)
    _check_options(rules, angles, crease_method, where)
    return crease_method


def _step(mesh: ControlMesh, rules: str, angles: str, crease_method: str, canonical: bool) -> tuple[sp.csr_matrix, ControlMesh]:
    ctx = _Context(mesh, crease_method)
    s = _operator(ctx, rules, angles, canonical)
    child = _child_mesh(ctx, s @ mesh.vertices)
    return s, child


#: Largest mesh ``subdivide`` makes: measured 1.4 kB of peak memory per face (cube, 8 steps:
#: 393k faces, 0.56 GB, 6 s), so 5.6 GB; 40 steps of a cube were killed for memory before.
MAX_SUBDIVIDE_FACES = 4_000_000


def subdivide(
    mesh: ControlMesh, steps: int = 1, rules: str = "seed", angles: str = "standard", crease_method: str | None = None
) -> ControlMesh:
    """``steps`` subdivision steps; the refined control mesh with its tags (options as
    :func:`subdivision_operator`)."""
    crease_method = _resolve(mesh, rules, angles, crease_method)
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
        _, mesh = _step(mesh, rules, angles, crease_method, canonical=False)
    return mesh
