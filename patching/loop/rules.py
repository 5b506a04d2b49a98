"""Loop subdivision masks and the crease logic, no mesh ([OSD] ``sdc/loopScheme.h``,
``sdc/crease.cpp``, ``sdc/scheme.h``), vectorised over arrays of configurations.

Masks (weights of the new point on the old points), [OSD] ``Scheme<SCHEME_LOOP>``:

* smooth edge: ``3/8 (a + b) + 1/8 (c + d)``, c and d opposite the edge in its two triangles;
* crease edge: ``(a + b) / 2``;
* smooth vertex of valence n: ``(1 - n beta_n) V + beta_n sum E_i`` with Loop's original
  ``beta_n = (5/8 - (3/8 + cos(2 pi / n) / 4)^2) / n`` (1/16 at n = 6);
* crease vertex: ``3/4 V + 1/8 (E_a + E_b)``, E_a, E_b the ends of its two sharp edges;
* corner vertex: ``V``.

Semi-sharp features ([OSD] ``Sdc::Scheme::ComputeEdgeVertexMask`` /
``ComputeVertexVertexMask`` as ``Far::PrimvarRefiner`` calls them): an edge of sharpness
``s > 0`` takes the crease mask when its child vertex is a crease (both child halves sharp),
otherwise ``s (crease) + (1 - s)(smooth)`` with ``s`` unclamped.  A vertex whose parent rule
is crease or corner and whose child rule differs blends ``w (parent mask) + (1 - w)(child
mask)`` with ``w = fractional_weight`` ([OSD] ``Crease::ComputeFractionalWeightAtVertex``).
Sharpness decays by one a step, or by [OSD]'s Chaikin rule (``child_edge_sharpness``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SMOOTH",
    "DART",
    "CREASE",
    "CORNER",
    "INFINITE",
    "loop_beta",
    "loop_limit_edge_weight",
    "decrement",
    "vertex_rule",
    "child_edge_sharpness",
    "fractional_weight",
]

#: Vertex rules by sharp-edge count, as [OSD] ``Sdc::Crease::Rule`` (0, 1, 2, > 2 or a sharp vertex).
SMOOTH, DART, CREASE, CORNER = 0, 1, 2, 3
#: Sharpness at or above which a feature is infinitely sharp ([OSD] ``SHARPNESS_INFINITE``).
INFINITE = 10.0


def loop_beta(n) -> np.ndarray:
    """Loop's neighbour weight ``beta_n = (5/8 - (3/8 + cos(2 pi/n)/4)^2) / n`` of the smooth
    vertex mask ([OSD] ``assignSmoothMaskForVertex``; 1/16 at n = 6)."""
    n = np.asarray(n, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 0.375 + 0.25 * np.cos(2.0 * np.pi / n)
        return np.where(n == 6, 0.0625, (0.625 - c * c) / n)


def loop_limit_edge_weight(n) -> np.ndarray:
    """Neighbour weight of Loop's smooth limit mask, ``1 / (n + 3 / (8 beta_n))`` (1/12 at
    n = 6), the centre getting ``1 - n`` times it ([OSD] ``assignSmoothLimitMask``)."""
    n = np.asarray(n, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n == 6, 1.0 / 12.0, 1.0 / (n + 3.0 / (8.0 * loop_beta(n))))


def decrement(s) -> np.ndarray:
    """[OSD] ``decrementSharpness``: 0 stays 0, infinite (>= 10) stays, else ``max(s - 1, 0)``."""
    s = np.asarray(s, dtype=np.float64)
    return np.where(s >= INFINITE, s, np.where(s > 1.0, s - 1.0, 0.0))


def vertex_rule(vertex_sharpness, sharp_edge_count) -> np.ndarray:
    """[OSD] ``DetermineVertexVertexRule``: corner if the vertex is sharp or has more than two
    sharp edges, else smooth, dart, crease for 0, 1, 2 sharp edges.  (v,) int8."""
    vs = np.asarray(vertex_sharpness)
    c = np.asarray(sharp_edge_count)
    return np.where((vs > 0) | (c > 2), CORNER, np.minimum(c, 2)).astype(np.int8)


def child_edge_sharpness(es: np.ndarray, edges: np.ndarray, n_vertices: int, method: str) -> np.ndarray:
    """(e, 2) sharpness of the child half of every edge at its end ``edges[:, k]``.

    ``uniform``: ``decrement(s)``.  ``chaikin`` ([OSD] ``SubdivideEdgeSharpnessesAroundVertex``
    with ``CREASE_CHAIKIN``): at a vertex with c semi-sharp edges (0 < s < 10), c >= 2, a
    semi-sharp edge's half gets ``3/4 s + 1/4 (mean of the other c - 1) - 1`` (0 if <= 0); with
    c = 1 (or a vertex of one edge) ``decrement(s)``; smooth and infinite halves keep theirs."""
    d = decrement(es)
    if method == "uniform":
        return np.stack([d, d], axis=1)
    semi = (es > 0) & (es < INFINITE)
    total = np.zeros(n_vertices)
    count = np.zeros(n_vertices)
    degree = np.bincount(edges.ravel(), minlength=n_vertices)
    for k in (0, 1):
        np.add.at(total, edges[semi, k], es[semi])
        np.add.at(count, edges[semi, k], 1.0)
    out = np.empty((es.size, 2))
    own = np.where(semi, es, 0.0)
    for k in (0, 1):
        v = edges[:, k]
        c, t = count[v], total[v]
        ch = 0.75 * own + 0.25 * (t - own) / np.maximum(c - 1.0, 1.0) - 1.0
        ch = np.where(ch > 0, ch, 0.0)
        out[:, k] = np.where(semi & (c > 1) & (degree[v] >= 2), ch, d)
    return out


def fractional_weight(parent_vs, child_vs, transition_sum, transition_count) -> np.ndarray:
    """[OSD] ``ComputeFractionalWeightAtVertex``: the mean of the sharpness of every feature
    that turns smooth this step (the vertex itself if ``parent_vs > 0`` and ``child_vs <= 0``,
    each incident edge whose sharpness > 0 has a child half <= 0 at this vertex), clamped to
    1; 0 when nothing turns smooth.  ``transition_sum``/``count`` are the edges' share."""
    parent_vs = np.asarray(parent_vs, dtype=np.float64)
    turn = (parent_vs > 0) & (np.asarray(child_vs) <= 0)
    s = transition_sum + np.where(turn, parent_vs, 0.0)
    c = transition_count + turn
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(c > 0, s / np.maximum(c, 1), 0.0)
    return np.minimum(w, 1.0)
