"""Inputs refused before any refinement: knot-interval patterns that no closed surface has,
judged on the user's mesh (a refinement of a zero strip inserts its knot again, which the
checks must not mistake for a tear)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from patching.util.graph import connected_components

from patching.errors import KnotError, UnsupportedError
from patching.topology.features import sharp_edges
from patching.topology.tables import Topology

__all__ = ["refuse_input", "refuse_torn_knots", "refuse_tiny_intervals", "refuse_zero_strips_between_creases", "TINY_INTERVAL_RATIO"]


def refuse_input(topo: Topology) -> None:
    """Every check of this module, on the user's (unrefined) mesh."""
    refuse_torn_knots(topo)
    refuse_tiny_intervals(topo)
    refuse_zero_strips_between_creases(topo)


def refuse_torn_knots(topo: Topology) -> None:
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
    spans = topo.face_spans
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


def refuse_tiny_intervals(topo: Topology) -> None:
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


def refuse_zero_strips_between_creases(topo: Topology) -> None:
    """A zero strip (one or more in a row) between two infinitely sharp interior edges: the
    strip's faces collapse (no patch, their two long sides one B-rep edge), but the patches on
    either side end on two different crease curves, so the surface tears there (before: an
    invalid B-rep, BrepError).  The intervals' eps -> 0 limit keeps a patch of no parametric
    width spanning the two curves, which this version does not build: UnsupportedError naming
    the user's zero edge and the two creases.  One crease beside the strip is the eps limit."""
    mesh = topo.mesh
    quad = mesh.face_sizes == 4
    base = mesh.face_offsets[:-1]
    spans = topo.face_spans
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

