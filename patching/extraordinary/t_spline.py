"""The T-spline baseline at extraordinary points: [SSEL13]'s construction ([FSLYJ]'s [32]),
reconstructed from what [FSLYJ] says of it, as ``build_operator(method="t-spline")``.

[FSLYJ] compares against [SSEL13] (Figs. 1, 12, 13, 15) and names three differences; [SSEL13]
itself is not among the seeds, so each part is read from [FSLYJ]:

1. Connecting functions from uniform angles theta_i = 2 pi / n: b_i = -2 d_{i-1} d_{i+1}
   cos(2 pi / n) ([FSLYJ] sec. 3.3, "which is used in [32]"): ``angles="uniform"`` of
   ``angle_configuration``.
2. No auxiliary anchors ([FSLYJ] sec. 3.1: "the use of auxiliary control points near an EP is
   another idea to improve the surface quality, and avoid ambiguous computations for the
   Bezier extraction"): the bicubic extraction around the EP is [SSEL13]'s, which [FSLYJ]
   sec. 3.5 step 1 quotes: face points F_i = bilinear(P_0, P_{E_i}, P_{F_i}, P_{E_{i+1}}) at
   (w_i, w_{i+1}), w_i = (d_{i-2} + d_{i+2}) / (d_{i-2} + d_{i+2} + 2 d_i + 2 a_i), edge points
   by eq. (1), the EP's Bezier point V by eq. (3).  That is our extraction with the anchors
   put at those face points (``auxiliary_points`` rule "first-ring": A_i = F_i): every other
   coefficient of the irregular faces then follows from the F_i by the same double-knot
   insertion ([FSLYJ] Fig. 7), and the EP's corner is V, the extraction's vertex point, not
   [LFS16]'s limit point.
3. The G1 perturbation as one constrained optimisation of a fairing energy ([FSLYJ] sec. 2:
   "the problem can be formalized as a constrained optimization problem [28, 32]"; sec. 3.4:
   "Unlike that in [32], our optimization is computed locally"; sec. 5: "the same fairing
   energy as that in [32]"): per EP (and per cluster of EPs joined by spokes) the G1
   unknowns minimise the thin-plate energy of the patches around it plus a small pull to the
   degree-elevated extraction, under G_0..G_3 and the fifth difference of every spoke
   (``cluster_fairing``, whose solve takes a cluster of one EP as well).  [SSEL13]'s exact
   energy, its weights and its set of unknowns are not in the seeds; this is the reading
   closest to [FSLYJ]'s words with the solver the project has.

Sector EPs (sharp spokes, [FSLYJ] sec. 4.2) keep their sector anchors: [SSEL13] has no sharp
features at EPs.  Everything else (regular faces, the bi-quintic layout, the interior rule)
is the same as the default method, so a comparison isolates these three choices.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from patching.extraordinary.cluster_fairing import ep_clusters

if TYPE_CHECKING:
    from patching.extraordinary.g1_patches import EPGroup
    from patching.topology.tables import Topology

__all__ = ["ANGLES", "ANCHOR_RULE", "t_spline_clusters"]

#: The angle configuration of [SSEL13]: theta_i = 2 pi / n.
ANGLES = "uniform"
#: The anchors of [SSEL13]'s extraction: its own first-ring face points.
ANCHOR_RULE = "first-ring"


def t_spline_clusters(groups: "list[EPGroup]", topo: "Topology") -> list[np.ndarray]:
    """The fairing problems: the clusters of EPs joined by spokes (``ep_clusters``), and every
    EP with no other EP at the far end of a spoke as a cluster of its own; (m, 2) arrays of
    (group index, row index).  EPs of clusters too large for ``ep_clusters`` keep the per-EP
    steps (a singleton there would share spoke rows with its neighbour's)."""
    clusters = ep_clusters(groups, topo)
    for k, g in enumerate(groups):
        alone = np.flatnonzero(np.all(g.far < 0, axis=1))
        clusters += [np.array([[k, int(e)]], dtype=np.int64) for e in alone]
    return clusters
