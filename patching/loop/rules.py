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
Sharpness decays by one a step, or by [OSD]'s Chaikin rule: ``decrement`` and
``child_edge_sharpness`` are ``patching.rules.crease``'s, shared with Catmull-Clark and
re-exported here.
"""

from __future__ import annotations

import numpy as np

from patching.rules.crease import INFINITE, child_edge_sharpness, decrement

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


def vertex_rule(vertex_sharpness, sharp_edge_count) -> np.ndarray:
    """[OSD] ``DetermineVertexVertexRule``: corner if the vertex is sharp or has more than two
    sharp edges, else smooth, dart, crease for 0, 1, 2 sharp edges.  (v,) int8."""
    vs = np.asarray(vertex_sharpness)
    c = np.asarray(sharp_edge_count)
    return np.where((vs > 0) | (c > 2), CORNER, np.minimum(c, 2)).astype(np.int8)


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
