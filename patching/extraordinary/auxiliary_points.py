"""Positions of the auxiliary control points (anchors) around an EP ([FSLYJ] sec. 3.5).

The anchors A_i (one per face i around an EP of valence n) are free; the default rule puts
them so that the patched surface has, at the EP, the limit point and the tangent plane of the
eigen-polyhedron subdivision of Li-Finnigan-Sederberg ([LFS16], ``eigen_polyhedron``):

1. A first ring [V, E_0.., F_0..] from the control points with the extraction of [SSEL13]:
   F_i = bilinear(P_0, P_{E_i}, P_{F_i}, P_{E_{i+1}}) at (w_i, w_{i+1}),
   w_i = (d_{i-2} + d_{i+2}) / (d_{i-2} + d_{i+2} + 2 d_i + 2 a_i), a_i the interval of the
   edge that continues spoke i beyond E_i (``onward_interval``: its reading at an irregular E_i);
   E_i = (d_{i-1} F_i + d_{i+1} F_{i-1}) / (d_{i-1} + d_{i+1});  V by eq. (3).
2. C = L^0 [V, E, F] (dominant left eigenvector of the local subdivision matrix N).
3. Vbar = Q Phat, the projection of [E - V, F - V] on the lambda-eigenspace of Nhat.
4. A_i = C - C' + Vbar_{n+i}, C' = sum_i c_i Vbar_{n+i}, c_i = the weight of A_i in the patch
   corner at the EP (eq. 3: c_i = d_{i-1} d_{i+2} / sum), so that corner is exactly C.
5. (ours) Plus the part of the dropped components that the EP cannot see: the difference
   between the "extraction" anchors below and these, projected onto the anchor changes that
   leave both the corner point (eq. 3) and the edge points on the spokes (eq. 1) unchanged.
   Those are all the stage-1 G1 solve reads of the tangent plane, so it stays [LFS16]'s exactly,
   while the twist comes back: at a forced valence-4 vertex with uniform intervals the
   bicubic B-spline is reproduced (its face points differ from their tangent-plane
   projections by an alternating pattern, which is in that null space).  For odd valence or
   generic intervals the null space is {0} and step 5 changes nothing.

All weights depend on intervals only; each anchor is a row over the 2n+1 mesh vertices of the
ring (P_0 the EP, then E_i = far end of spoke i, then F_i = far corner of face i).

Step 3 projects the anchors onto the tangent plane: every first-order input of the G1 solve
at the EP then lies in that plane, which is what makes the surface's tangent plane exactly
[LFS16]'s, but it also drops the twist and curvature of the ring; step 5 gives back the part of
them that no first-order input sees.  ``rule="extraction"`` keeps every component instead: A_i = F_i + C - sum_j c_j F_j
(the first-ring face points moved so that the corner is still [LFS16]'s limit point C); it
reproduces the B-spline at a forced valence-4 vertex with uniform intervals, and its tangent
plane is [LFS16]'s only approximately.  Both are offered; section 3.5's rule is the default.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from patching.rules.eigen_polyhedron import limit_and_projectors, limit_point_weights, tangent_projector
from patching.topology.tables import Topology
from patching.util.memo import batching, memo
from patching.util.solve_cache import lookup, lookup_many
from patching.util.sparse_rows import TripletRows

__all__ = ["RULES", "anchor_weights", "anchor_weights_batch", "anchor_matrix", "onward_interval", "vertex_point_weights"]


def vertex_point_weights(d: np.ndarray) -> np.ndarray:
    """c_i = d_{i-1} d_{i+2} / sum (eq. 3): weight of the face point of face i at the vertex."""
    w = np.roll(d, 1) * np.roll(d, -2)
    return w / w.sum()


#: "first-ring": A_i = F_i, the extraction of [SSEL13] itself (no limit point of [LFS16]), so
#: that the patches are [SSEL13]'s C0 extraction with the EP as control point
#: (``t_spline``, ``build_operator(method="t-spline")``).
RULES = ("eigen-polyhedron", "extraction", "first-ring")


def _anchor_valid(args: tuple, arrays: list[np.ndarray]) -> bool:
    """A cache entry of ``_anchor_weights(*args)`` is trusted if it is n x (2n + 1) with rows
    summing to 1."""
    n = len(args[0])
    (w,) = arrays
    return w.shape == (n, 2 * n + 1) and bool(np.all(np.abs(w.sum(axis=1) - 1.0) <= 1e-9))


@memo(4096)
def _anchor_weights(d: tuple, a: tuple, angles: str, rule: str) -> np.ndarray:
    """``_anchor_solve`` through the persistent cache of ``patching.util.solve_cache`` (when one
    is installed; ``_anchor_valid`` judges an entry)."""
    args = (d, a, angles, rule)
    (out,) = lookup("anchor_weights", args, 1, lambda: [_anchor_solve(d, a, angles, rule)], lambda x: _anchor_valid(args, x))
    out.setflags(write=False)
    return out


def _anchor_solve(d: tuple, a: tuple, angles: str, rule: str) -> np.ndarray:
    d_arr = np.array(d)
    a_arr = np.array(a)
    n = d_arr.size
    size = 2 * n + 1
    E = lambda i: 1 + (i % n)  # noqa: E731
    F = lambda i: 1 + n + (i % n)  # noqa: E731
    before = np.roll(d_arr, 2) + np.roll(d_arr, -2)
    w = before / (before + 2 * d_arr + 2 * a_arr)
    ring = np.zeros((size, size))  # rows: V, E_i, F_i of the first ring; columns: P_0, E_i, F_i
    for i in range(n):
        wi, wj = w[i], w[(i + 1) % n]
        row = ring[F(i)]
        row[0] += (1 - wi) * (1 - wj)
        row[E(i)] += wi * (1 - wj)
        row[F(i)] += wi * wj
        row[E(i + 1)] += (1 - wi) * wj
    for i in range(n):
        dm, dp = d_arr[(i - 1) % n], d_arr[(i + 1) % n]
        ring[E(i)] = (dm * ring[F(i)] + dp * ring[F(i - 1)]) / (dm + dp)
    c = vertex_point_weights(d_arr)
    ring[0] = sum(c[i] * ring[F(i)] for i in range(n))
    if rule == "first-ring":
        out = ring[n + 1 :].copy()
        out.setflags(write=False)
        return out
    limit = limit_point_weights(d_arr, angles=angles) @ ring  # C
    if rule == "extraction":
        out = ring[n + 1 :] + (limit - ring[0])[None, :]  # A_i = F_i + C - V, V = sum c_j F_j
        out.setflags(write=False)
        return out
    vbar = tangent_projector(d_arr, angles=angles) @ ring  # (2n, size), rows E then F
    faces = vbar[n:]
    shift = c @ faces  # C'
    out = limit[None, :] - shift[None, :] + faces
    # Step 5: give back what the projection dropped and nothing at the EP sees (see module
    # docstring): the part of (extraction anchors - projected anchors) in the null space of
    # the map anchors -> [P00 (eq. 3), edge points on the spokes (eq. 1)].
    extraction = ring[n + 1 :] + (limit - ring[0])[None, :]
    invisible = _invisible_projector(tuple(d))
    out = out + invisible @ (extraction - out)
    out.setflags(write=False)
    return out


def _anchor_solve_batch(d: np.ndarray, a: np.ndarray, angles: str, rule: str) -> np.ndarray:
    """``_anchor_solve`` of g configurations of one valence at once: d, a (g, n) -> (g, n,
    2n+1), the same steps with every ring row a (g,)-vector operation and the eigen-analysis
    of all g rings in one batched call (``limit_and_projectors``)."""
    g, n = d.shape
    size = 2 * n + 1
    rows = np.arange(g)
    before = np.roll(d, 2, axis=1) + np.roll(d, -2, axis=1)
    w = before / (before + 2 * d + 2 * a)
    ring = np.zeros((g, size, size))
    for i in range(n):
        wi, wj = w[:, i], w[:, (i + 1) % n]
        fi, ei, ej = 1 + n + i, 1 + i, 1 + (i + 1) % n
        ring[rows, fi, 0] += (1 - wi) * (1 - wj)
        ring[rows, fi, ei] += wi * (1 - wj)
        ring[rows, fi, fi] += wi * wj
        ring[rows, fi, ej] += (1 - wi) * wj
    for i in range(n):
        dm, dp = d[:, (i - 1) % n, None], d[:, (i + 1) % n, None]
        ring[:, 1 + i] = (dm * ring[:, 1 + n + i] + dp * ring[:, 1 + n + (i - 1) % n]) / (dm + dp)
    cw = np.roll(d, 1, axis=1) * np.roll(d, -2, axis=1)
    c = cw / cw.sum(axis=1, keepdims=True)  # vertex_point_weights per row
    ring[:, 0] = sum(c[:, i, None] * ring[:, 1 + n + i] for i in range(n))
    if rule == "first-ring":
        return ring[:, n + 1 :].copy()
    weights, projector = limit_and_projectors(d, angles=angles)
    limit = np.einsum("gs,gst->gt", weights, ring)  # C
    extraction = ring[:, n + 1 :] + (limit - ring[:, 0])[:, None, :]
    if rule == "extraction":
        return extraction
    faces = (projector @ ring)[:, n:]  # V-bar of the faces
    shift = np.einsum("gi,gis->gs", c, faces)  # C'
    out = limit[:, None, :] - shift[:, None, :] + faces
    invisible = np.stack([_invisible_projector(tuple(row)) for row in d.tolist()])  # step 5
    return out + invisible @ (extraction - out)


def anchor_weights_batch(d: np.ndarray, a: np.ndarray, angles: str = "standard", rule: str = "eigen-polyhedron") -> np.ndarray:
    """:func:`anchor_weights` of g configurations of one valence: d, a (g, n) -> (g, n, 2n+1).
    Those not solved before in this process are read from the persistent cache (when one is
    installed) or solved in one batch (``_anchor_solve_batch``); equal to the one-configuration
    function row for row (to round-off: the batched products may sum in another order)."""
    if rule not in RULES:
        raise ValueError(f"anchor rule must be one of {RULES}, not {rule!r}")
    d, a = np.asarray(d, dtype=np.float64), np.asarray(a, dtype=np.float64)
    configs = [(tuple(x), tuple(y), angles, rule) for x, y in zip(d.tolist(), a.tolist())]
    if not batching():
        return np.array([_anchor_weights(*args) for args in configs]).reshape(d.shape + (2 * d.shape[1] + 1,))
    todo = list(dict.fromkeys(args for args in configs if not _anchor_weights.known(args)))

    def solve_many(args_list: list[tuple]) -> list[list[np.ndarray]]:
        out = _anchor_solve_batch(np.array([x[0] for x in args_list]), np.array([x[1] for x in args_list]), angles, rule)
        return [[w] for w in out]

    if todo:
        for args, (w,) in zip(todo, lookup_many("anchor_weights", todo, 1, solve_many, _anchor_valid)):
            w.setflags(write=False)
            _anchor_weights.prime(args, w)
    return np.array([_anchor_weights(*args) for args in configs]).reshape(d.shape + (2 * d.shape[1] + 1,))


@lru_cache(maxsize=4096)
def _invisible_projector(d: tuple) -> np.ndarray:
    """(n, n) orthogonal projector onto the anchor combinations x with sum_i c_i x_i = 0 and
    d_{i-1} x_i + d_{i+1} x_{i-1} = 0 for every spoke i: changes of the anchors that move
    neither the EP's corner point nor the edge points next to it.  Uniform even valence: the
    alternating pattern (+, -, +, -, ...), the twist; odd valence or generic intervals: {0}."""
    d_arr = np.array(d)
    n = d_arr.size
    rows = np.zeros((n + 1, n))
    rows[0] = vertex_point_weights(d_arr)
    for i in range(n):
        rows[1 + i, i] += d_arr[(i - 1) % n]
        rows[1 + i, (i - 1) % n] += d_arr[(i + 1) % n]
    _, sv, vt = np.linalg.svd(rows)
    z = vt[int(np.count_nonzero(sv > 1e-12 * sv.max())) :].T
    out = z @ z.T
    out.setflags(write=False)
    return out


def anchor_weights(d, a, angles: str = "standard", rule: str = "eigen-polyhedron") -> np.ndarray:
    """(n, 2n+1) weights of the anchors A_0..A_{n-1} over [P_0, E_0.., F_0..]; rows sum to 1."""
    if rule not in RULES:
        raise ValueError(f"anchor rule must be one of {RULES}, not {rule!r}")
    return _anchor_weights(tuple(float(x) for x in d), tuple(float(x) for x in a), angles, rule)


def onward_interval(topo: Topology, h: np.ndarray) -> np.ndarray:
    """a_i of section 3.5 step 1 for spokes h (P_0 -> E_i) whose far end E_i is an interior vertex.

    The seed defines a_i as "the knot interval of the edge adjacent to the i-th spoke edge",
    the edge that continues the spoke straight beyond E_i; that exists only where E_i has
    valence 4 (Fig. 11 draws regular neighbours).  Reconstruction for an irregular E_i: the
    spoke back from E_i to P_0 is spoke j of E_i, and w_i reads "the interval behind" P_0 as
    (d_{i-2} + d_{i+2}) / 2; the same reading at E_i gives a_i = (d'_{j-2} + d'_{j+2}) / 2 over
    E_i's own spokes.  At valence 4 both are the straight continuation (the seed's a_i); in
    general it makes the rule symmetric along the edge: the first-ring face points of both
    ends sit at w = B_0 / (B_0 + d_i + B_1) and w' = B_1 / (B_1 + d_i + B_0) of the edge, so
    w + w' < 1 and they never cross.  The earlier reading a_i = d_i put them past each other
    on short edges between two EPs (w = 0.55 at valence 3 with intervals 1.2 against 2.1 and
    3.5), which folded the catmark cube's patches at interval ratio 3."""
    back = topo.twin[h]
    ahead = topo.rotate(topo.rotate(back))
    behind = topo.rotate_back(topo.rotate_back(back))
    iv = topo.halfedge_interval
    return 0.5 * (iv[ahead] + iv[behind])


def anchor_matrix(
    topo: Topology, groups, anchor_column: np.ndarray, n_points: int, angles: str = "standard", rule: str = "eigen-polyhedron"
) -> sp.csr_matrix:
    """(n_anchors, n_points) sparse: the anchors as combinations of control points.

    groups: ``g1_patches.EPGroup`` per valence; weights are computed once per distinct
    (intervals, onward intervals) configuration."""
    n_anchors = int(np.count_nonzero(anchor_column >= 0))
    triplets = TripletRows()
    inner = ~topo.vertex_is_boundary & (topo.valence >= 3)
    for g in groups:
        h = g.h
        ends = topo.dest[h]
        far_corner = topo.dest[topo.next[h]]
        a = np.where(inner[ends], onward_interval(topo, h), g.d)
        config = np.concatenate([g.d, a], axis=1)
        uniq, inverse = np.unique(config, axis=0, return_inverse=True)
        table = anchor_weights_batch(uniq[:, : g.n], uniq[:, g.n :], angles, rule)
        weights = table[inverse.ravel()]  # (E, n, 2n+1)
        ids = np.concatenate([g.vertices[:, None], ends, far_corner], axis=1)  # (E, 2n+1)
        anchor_rows = anchor_column[h] - n_points  # (E, n)
        triplets.add(anchor_rows[:, :, None], ids[:, None, :], weights)
    return triplets.matrix((n_anchors, n_points))
