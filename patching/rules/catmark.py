"""Subdivision masks only: weights for face, edge and vertex points, no mesh (like
OpenSubdiv's ``sdc/``).  ``subdivision`` gathers the knot intervals and tags from the topology
and calls these, vectorised over arrays of configurations.

Curve rules (the building block of every regular rule): a cubic B-spline with control points
``... P_{i-1}, P_i, P_{i+1} ...``; the edge ``P_j P_{j+1}`` carries the knot interval ``d_j``
(docs/knots.md).  Inserting a knot at the middle of every interval (each interval split into two
halves) gives, [SZSS98] and [TLC] eqs. (11)-(13):

    edge point on P_i P_{i+1}:
        E_i = ((d_i + 2 d_{i+1}) P_i + (d_i + 2 d_{i-1}) P_{i+1}) / (2 (d_{i-1} + d_i + d_{i+1}))
    vertex point at P_i:
        V_i = (d_i E_{i-1} + (d_{i-1} + d_i) P_i + d_{i-1} E_i) / (2 (d_{i-1} + d_i))

[TLC] writes both with the intervals beyond the two neighbours equal to the spoke's own
(its eqs. 12-13 are the edge rule with ``d_{i+1} = d_i``); written here in general, and checked
(tests) against OpenCASCADE's knot insertion on torus grids.  Uniform intervals give the
classic ``(1/2, 1/2)`` and ``(1/8, 3/4, 1/8)``.  Every mask is invariant under scaling all
intervals, and its weights sum to one.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

__all__ = [
    "curve_edge_weights",
    "curve_vertex_weights",
    "blz_gamma",
    "curve_limit_weights",
    "curve_derivative_weights",
    "tagged_vertex_rules",
    "tagged_rules_batch",
    "SMOOTH",
    "DART",
    "CREASE",
    "CORNER",
]

#: Vertex rules, numbered as OpenSubdiv's Sdc::Crease::Rule by sharp-edge count (0, 1, 2, >2).
SMOOTH, DART, CREASE, CORNER = 0, 1, 2, 3


def curve_edge_weights(d_prev, d, d_next):
    """Weights ``(w_i, w_{i+1})`` of the midpoint-insertion edge point of ``P_i P_{i+1}``.

    d_prev = d_{i-1} (beyond P_i), d = d_i (the edge), d_next = d_{i+1} (beyond P_{i+1}); arrays
    broadcast.  A zero total (three zero intervals) is a point of multiplicity four: the
    midpoint is returned there.
    """
    d_prev, d, d_next = (np.asarray(x, dtype=np.float64) for x in (d_prev, d, d_next))
    total = 2.0 * (d_prev + d + d_next)
    safe = np.where(total > 0, total, 1.0)
    w_i = np.where(total > 0, (d + 2.0 * d_next) / safe, 0.5)
    return w_i, 1.0 - w_i


def curve_vertex_weights(d_mm, d_m, d_p, d_pp):
    """Weights ``(w_{i-1}, w_i, w_{i+1})`` of the midpoint-insertion vertex point at ``P_i``.

    d_mm = d_{i-2}, d_m = d_{i-1} (edge P_{i-1} P_i), d_p = d_i (edge P_i P_{i+1}),
    d_pp = d_{i+1}.  From V_i above with E_{i-1}, E_i expanded:
    ``w_{i-1} = d_i (d_{i-1} + 2 d_i) / (4 (d_{i-1} + d_i)(d_{i-2} + d_{i-1} + d_i))`` and its
    mirror image; ``w_i = 1 - w_{i-1} - w_{i+1}``.
    """
    d_mm, d_m, d_p, d_pp = (np.asarray(x, dtype=np.float64) for x in (d_mm, d_m, d_p, d_pp))
    s = d_m + d_p
    den_m = 4.0 * s * (d_mm + d_m + d_p)
    den_p = 4.0 * s * (d_m + d_p + d_pp)
    w_m = np.where(den_m > 0, d_p * (d_m + 2.0 * d_p) / np.where(den_m > 0, den_m, 1.0), 0.0)
    w_p = np.where(den_p > 0, d_m * (d_p + 2.0 * d_m) / np.where(den_p > 0, den_p, 1.0), 0.0)
    return w_m, 1.0 - w_m - w_p, w_p


def blz_gamma(theta):
    """Biermann-Levin-Zorin's edge weight next to a tagged vertex: ``3/8 - cos(theta)/4``
    ([TLC] sec. 2).  The tagged end gets ``3/4 - gamma``, the other end ``gamma``, the
    four far vertices ``1/16`` each; ``theta = pi/2`` gives the standard ``3/8``."""
    return 0.375 - 0.25 * np.cos(np.asarray(theta, dtype=np.float64))


def curve_limit_weights(a, b):
    """Limit position of a stationary curve vertex: weights ``(w_{-1}, w_0, w_{+1})``.

    After one step every vertex point has the same interval on both halves of each side:
    ``a`` (twice) towards ``P_{-1}``, ``b`` (twice) towards ``P_{+1}``; the curve rules on
    ``(P_{-1}, P_0, P_{+1})`` are then a closed 3x3 matrix whose left eigenvector of eigenvalue 1
    is (derived symbolically, checked in the tests against repeated subdivision):
    ``(b^2 / ((a+b)(2a+b)), 6ab / ((a+2b)(2a+b)), a^2 / ((a+b)(a+2b)))``; uniform: (1, 4, 1)/6,
    the value of the cubic B-spline at the knot between the two intervals.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return (
        b * b / ((a + b) * (2 * a + b)),
        6 * a * b / ((a + 2 * b) * (2 * a + b)),
        a * a / ((a + b) * (a + 2 * b)),
    )


def curve_derivative_weights(a, b):
    """Derivative of the stationary curve at its vertex with respect to the knot parameter:
    weights on ``(P_{-1}, P_0, P_{+1})``, summing to 0.

    The left eigenvector of eigenvalue 1/2 of the same 3x3 matrix,
    ``(-b (a+2b), -2 (a-b)(a+b), a (2a+b))``, normalised so that it gives 1 on the Greville
    abscissae ``(-a, (b-a)/3, b)`` (linear precision): divided by
    ``(a+b)(9ab + 2(a-b)^2)/3``.  Uniform unit intervals: ``(P_{+1} - P_{-1}) / 2``.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    scale = 3.0 / ((a + b) * (9 * a * b + 2 * (a - b) ** 2))
    return -b * (a + 2 * b) * scale, -2 * (a - b) * (a + b) * scale, a * (2 * a + b) * scale


# ------------------------------------------------------------------------------------------
# [TLC] sec. 4: generalised eigen-polyhedra at tagged vertices (non-uniform intervals)

KINDS = {DART: "dart", CREASE: "crease", CORNER: "corner"}


class TaggedRules(NamedTuple):
    """``matrix`` (size, size) local rows, ``defined`` (size,) bool, ``polyhedron`` (size, 2)
    the generalised eigen-polyhedron P^0, ``translation`` (2,) T: defined rows satisfy
    ``matrix @ polyhedron = polyhedron / 2 + T`` (for a corner: in each sector's own frame;
    ``polyhedron`` is then the first sector's)."""

    matrix: np.ndarray
    defined: np.ndarray
    polyhedron: np.ndarray
    translation: np.ndarray


@functools.lru_cache(maxsize=4096)
def tagged_vertex_rules(kind: int, intervals: tuple, sharp: tuple, boundary: bool) -> TaggedRules:
    """Local rules around one tagged vertex (:func:`tagged_rules_batch` for one vertex, cached
    by its arguments); arrays read-only."""
    rules = tagged_rules_batch(kind, np.array(intervals, dtype=np.float64)[None], sharp, boundary)
    out = TaggedRules(rules.matrix[0], rules.defined, rules.polyhedron[0], rules.translation[0])
    for a in out:
        a.flags.writeable = False
    return out


@functools.lru_cache(maxsize=256)
def _frames(kind: int, n: int, sharp: tuple, boundary: bool):
    """Spoke angles of the generalised eigen-polyhedron, per frame: (phi (frames, n), face_frame
    (nf,), spoke_frame (n,)), from topology only.  Dart and crease: one frame (their sectors
    add up to 2 pi, or pi on a boundary).  Corner: "we deal with each sector separately" (seed
    000 section 4.1): one frame per sector, so that sectors whose angles do not add up to 2 pi
    do not overlap; a face or an untagged spoke lies inside one sector and uses its frame."""
    nf = n - 1 if boundary else n
    face_frame = np.zeros(nf, np.int64)
    spoke_frame = np.zeros(n, np.int64)
    if kind == DART:
        return (2 * math.pi * np.arange(n) / n)[None], face_frame, spoke_frame
    cuts = list(sharp) if sharp else [0]
    bounds = []
    for q, s0 in enumerate(cuts):
        s1 = cuts[q + 1] if q + 1 < len(cuts) else (cuts[0] + n if not boundary else n - 1)
        if s1 > s0:
            bounds.append((s0, s1))
    if kind == CREASE:
        theta = np.empty(nf)
        for s0, s1 in bounds:
            for j in range(s0, s1):
                theta[j % nf if not boundary else j] = math.pi / (s1 - s0)
        return np.concatenate([[0.0], np.cumsum(theta)])[:n][None], face_frame, spoke_frame
    phis = np.zeros((len(bounds), n))
    for q, (s0, s1) in enumerate(bounds):
        for j in range(s0, s1 + 1):
            phis[q, j % n] = 0.5 * math.pi * (j - s0)  # alpha_q / n_q = pi/2 (quads)
        for j in range(s0, s1):
            face_frame[j % nf if not boundary else j] = q
        for j in range(s0 + 1, s1):
            spoke_frame[j % n] = q
    return phis, face_frame, spoke_frame


def tagged_rules_batch(kind: int, intervals: np.ndarray, sharp: tuple, boundary: bool) -> TaggedRules:
    """Local rules around g tagged vertices of one kind and shape from [TLC]'s generalised
    eigen-polyhedron, all at once.

    kind: DART, CREASE or CORNER.  intervals: (g, n) spoke intervals d_0..d_{n-1} of each
    vertex (rotation order; for an interior dart or crease, spoke 0 is a sharp spoke).  sharp:
    indices of the sharp spokes (sorted).  boundary: spokes 0 and n-1 are the boundary edges
    and there are n-1 faces.  Local points [V, E_0..E_{n-1}, F_0..F_{nf-1}], face i = (V, E_i,
    F_i, E_{i+1}).  Returns TaggedRules (M, defined, P^0, T): M (g, size, size) float64, rows
    of the new points; defined (size,) bool: every face row, the rows of untagged spokes, and
    the vertex row of a dart; P^0 (g, size, 2); T (g, 2).  The crease and corner vertex rows
    and the crease edges are the curve rules (``subdivision``), not here.  Raises
    ``eigen_polyhedron.BilinearError`` whose ``index[0]`` is the failing vertex.

    Construction ([TLC] secs. 4.1-4.3): ``V^ = 0``; ``E^_i = l_i (cos phi_i, sin phi_i)``
    with l_i of eq. (5) (``eigen_polyhedron.spoke_lengths(d, "fourier")``; ``l = d`` for two
    spokes) and angles per sector (:func:`_frames`): dart ``2 pi / n``; crease ``pi / n_1`` and
    ``pi / n_2``; corner ``alpha_q / n_q`` with the sector's topological angle (``pi/2`` a
    quad, see ``subdivision``); ``F^_i = E^_i + E^_{i+1}``; ``lambda = 1/2``; ``T = V^1`` from
    the vertex rule: dart eq. (9)-(10) (the two half-sums weighted with mu = y_2 / (y_2 - y_1)
    so that ``T`` lies on the sharp spoke), crease eq. (14), corner 0.  Face rows: the bilinear
    form (18) solved for ``F^1 = F^0/2 + T`` (eqs. 19-21); untagged edge rows: eqs. (23)-(28),
    the bilinear form on ``(P_{i,k} + V or E_i)/2`` solved for ``E^1 = E^0/2 + T``: both by
    ``eigen_polyhedron.bilinear_rule``, the closed form, every face (edge) of every vertex in
    one vectorised solve.  Reconstruction: eq. (7)'s ``f_i`` is printed as a garbled product;
    ``d_{i-1} d_{i+2}`` as in [FSLYJ] (and ``eigen_polyhedron``).  Check (tests): equal
    intervals give the BLZ rules (centroid faces, ``gamma = 3/8 - cos(theta)/4`` edges,
    Catmull-Clark darts).

    Zero spokes (a multiple knot, docs/knots.md) are taken, and the rules there are the limit of
    the rules with the zero intervals replaced by eps -> 0.  Why the limit exists and equals
    the rule at 0: every ingredient is a continuous function of the intervals wherever it is
    defined at them, so no separate formula is needed at 0.  The lengths of eq. (5) are
    linear in d (a zero spoke keeps ``l_k = (sum_j d_j |cos|) / 3 > 0`` while a spoke not
    at right angles to it is positive).  The vertex terms (eqs. 6-10: ``g_i``, ``f_i``,
    ``m_i``, mu) and the crease ``T`` (eq. 14) are rational with nonzero denominators.  The
    bilinear solves (eqs. 18-21, 23-28) are the inverse of a bilinear map, smooth where the
    root is simple (implicit function theorem).  So the rows are smooth in d there, and the
    eps rules differ from the rule at 0 by O(eps): measured, about 1e-8 at eps = 1e-8 for
    one zero spoke, dart, crease and corner, valence 3-6 (tests).  Where an ingredient is
    undefined at 0 the limit is not that of the
    formula: two opposite zero spokes at valence 4 (``l = 0``, ``E^_k = V^``: a degenerate
    polyhedron), two zero sharp spokes at a crease (``T`` is 0/0), two zero spokes next to
    each other at a dart.  Those raise BilinearError (no real root, or a non-finite row),
    never a row of NaN.  ``subdivision`` does not use these rules at zero spokes yet:
    the limit keeps the zero spoke at length ``l_k > 0``, so the refined points across a
    zero strip stop coinciding and the patches beside the strip (which gives none) do not
    close up (``subdivision._refuse_tagged_on_zero``).
    """
    from patching.rules import eigen_polyhedron as eig

    d = np.asarray(intervals, dtype=np.float64)
    g, n = d.shape
    nf = n - 1 if boundary else n
    size = 1 + n + nf
    ell = eig.spoke_lengths(d, "fourier", zero_spokes=True) if n >= 3 else d.copy()
    phis, face_frame, spoke_frame = _frames(kind, n, tuple(sorted(sharp)), boundary)
    # frames (g, frames, size, 2): V^ = 0, E^_i, F^_i = E^_i + E^_{i+1}
    e_hat = ell[:, None, :, None] * np.stack([np.cos(phis), np.sin(phis)], axis=-1)[None]
    f_hat = e_hat[:, :, :nf] + e_hat[:, :, (np.arange(nf) + 1) % n]
    frames = np.concatenate([np.zeros((g, phis.shape[0], 1, 2)), e_hat, f_hat], axis=2)
    P = frames[:, 0]
    lam = 0.5
    M = np.zeros((g, size, size))
    defined = np.zeros(size, bool)
    if kind == DART:
        hg, w = eig.spoke_terms(d, zero_spokes=True)  # (g, n, 2n + 1): a dart is interior, so size = 2n + 1
        half = (n - 1) // 2 + 1
        xa, xb = hg[:, :half].sum(1), hg[:, half:].sum(1)
        wa, wb = w[:, :half].sum(1), w[:, half:].sum(1)
        y1, y2 = np.einsum("gs,gs->g", xa, P[..., 1]), np.einsum("gs,gs->g", xb, P[..., 1])
        mu = y2 / (y2 - y1)
        row = (3.0 / n) * (mu[:, None] * xa + (1 - mu[:, None]) * xb) / (mu * wa + (1 - mu) * wb)[:, None]
        row[:, 0] += (n - 3.0) / n
        M[:, 0] = row
        defined[0] = True
        t_vec = np.einsum("gs,gsd->gd", row, P)
    elif kind == CREASE:
        k = sorted(sharp)[1]
        a, b = d[:, :1], d[:, k : k + 1]
        t_vec = (2 * a * (b + 2 * a) ** 2 * P[:, 1 + k] + 2 * b * (2 * b + a) ** 2 * P[:, 1]) / (
            8 * (b + a) * (2 * b + a) * (b + 2 * a)
        )
    else:
        t_vec = np.zeros((g, 2))

    # Face rows, eqs. (18)-(21), and untagged edge rows, eqs. (23)-(28): one solve each.
    k = np.arange(nf)
    e, e_next, f = 1 + k, 1 + (k + 1) % n, 1 + n + k
    M[:, f], alpha = eig.bilinear_rule(
        eig.face_corners(size, e, e_next, f), frames[:, face_frame],
        t_vec[:, None] + lam * frames[:, face_frame, f], f"{KINDS[kind]} face"
    )
    defined[f] = True
    spokes = np.array([i for i in range(n) if i not in sharp and not (boundary and i in (0, n - 1))], np.int64)
    if spokes.size:
        h = (spokes - 1) % nf if not boundary else spokes - 1
        e, e_prev, e_next = 1 + spokes, 1 + (spokes - 1) % n, 1 + (spokes + 1) % n
        corners = eig.edge_corners(size, e, e_prev, e_next, 1 + n + h, 1 + n + spokes, alpha[:, h, 0], alpha[:, spokes, 1])
        Q = frames[:, spoke_frame[spokes]]
        M[:, e], _ = eig.bilinear_rule(
            corners, Q, t_vec[:, None] + lam * frames[:, spoke_frame[spokes], e], f"{KINDS[kind]} edge", spokes
        )
        defined[e] = True
    bad = np.flatnonzero(~np.isfinite(M[:, defined]).all(axis=(1, 2)))
    if bad.size:  # zero spokes where the formulas are 0/0 (docstring)
        raise eig.BilinearError(
            f"{KINDS[kind]} vertex with spoke intervals {d[bad[0]].tolist()}: the rules are "
            f"undefined (0/0) at these zero intervals", (int(bad[0]),)
        )
    return TaggedRules(M, defined, P, t_vec)
